"""Codecs: one interface (:class:`Codec`), one registry (:data:`CODECS`, :func:`create`).

Every codec family is a sub-package; the modules beside them are the machinery the families share (interface,
registry, container, limits, segments, windows, skeleton blob, model file). Importing this package imports every
sub-package so that the registry is full: a new family only needs a folder whose ``__init__`` imports its
``@register_codec`` classes. Codecs live inside the ``mocapbench`` package because a top-level ``codecs`` package
would shadow Python's standard ``codecs`` module.
"""

import importlib
import pkgutil

from mocapbench.codecs.base import BitstreamError, Codec, CodecConfig, Decoded, NotFittedError, param
from mocapbench.codecs.limits import DEFAULT_LIMITS, DecodeLimitError, DecodeLimits, using_limits
from mocapbench.codecs.registry import (
    CODECS,
    UNAVAILABLE,
    CodecUnavailableError,
    codec_names,
    create,
    register_codec,
    register_unavailable,
)

for _module in pkgutil.iter_modules(__path__):
    if _module.ispkg and not _module.name.startswith("_"):
        importlib.import_module(f"{__name__}.{_module.name}")

__all__ = [
    "BitstreamError",
    "DecodeLimits",
    "DecodeLimitError",
    "DEFAULT_LIMITS",
    "using_limits",
    "Codec",
    "CodecConfig",
    "Decoded",
    "NotFittedError",
    "param",
    "CODECS",
    "UNAVAILABLE",
    "CodecUnavailableError",
    "codec_names",
    "create",
    "register_codec",
    "register_unavailable",
]
