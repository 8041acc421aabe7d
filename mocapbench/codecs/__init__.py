"""Codecs: one interface (:class:`Codec`), one registry (:data:`CODECS`, :func:`create`).

Importing this package imports every codec module in it so that the registry is full (a new codec module
only needs ``@register_codec``). Codecs live inside the ``mocapbench`` package because a top-level ``codecs``
package would shadow Python's standard ``codecs`` module.
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

_INFRASTRUCTURE = {"base", "registry", "container", "skeleton_blob", "limits", "windows"}
for _module in pkgutil.iter_modules(__path__):
    if _module.name not in _INFRASTRUCTURE and not _module.name.startswith("_"):
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
