"""The one codec registry: ``@register_codec`` fills ``CODECS``; ``create`` is every Hydra config's ``_target_``."""

from __future__ import annotations

import dataclasses
from typing import Any

from mocapbench.codecs.base import Codec

__all__ = [
    "CODECS",
    "UNAVAILABLE",
    "CodecUnavailableError",
    "register_codec",
    "register_unavailable",
    "create",
    "codec_names",
]

CODECS: dict[str, type[Codec]] = {}
# Codecs that exist but cannot run here (a missing optional package, compiler or library folder):
# name -> one line saying what is missing and how to get it.
UNAVAILABLE: dict[str, str] = {}


class CodecUnavailableError(RuntimeError):
    """A known codec that cannot run on this machine; the message says what is missing and how to get it."""


def register_unavailable(name: str, reason: str) -> None:
    """Record that codec ``name`` exists but cannot run here, with a one-line ``reason``."""
    if "\n" in reason:
        raise ValueError(f"the reason for {name!r} must be one line, got {reason!r}")
    if name not in CODECS:
        UNAVAILABLE[name] = reason


def register_codec(cls: type[Codec]) -> type[Codec]:
    """Class decorator: add ``cls`` to :data:`CODECS` under ``cls.name``; a duplicate name is an error."""
    name = getattr(cls, "name", None)
    if not isinstance(name, str) or not name:
        raise TypeError(f"{cls.__qualname__} needs a class attribute `name` (the registry key).")
    if name in CODECS and CODECS[name] is not cls:
        raise ValueError(f"Codec name {name!r} is already registered by {CODECS[name].__qualname__}.")
    if not dataclasses.is_dataclass(getattr(cls, "Config", None)):
        raise TypeError(f"{cls.__qualname__} needs a dataclass `Config`.")
    CODECS[name] = cls
    UNAVAILABLE.pop(name, None)
    return cls


def codec_names() -> list[str]:
    """Registered codec names, sorted."""
    return sorted(CODECS)


def create(name: str, **params: Any) -> Codec:
    """Build the codec registered as ``name`` with config fields ``params``.

    Raises
    ------
    KeyError
        For an unknown codec name (the message lists the known ones).
    TypeError
        For an unknown parameter (the message lists the config's fields).
    ValueError
        For a parameter out of its range (raised by the config, naming the field).
    """
    if name in UNAVAILABLE and name not in CODECS:
        raise CodecUnavailableError(f"codec {name!r} is unavailable here: {UNAVAILABLE[name]}")
    if name not in CODECS:
        raise KeyError(f"Unknown codec {name!r}; registered codecs are {codec_names()}.")
    cls = CODECS[name]
    fields = {field.name for field in dataclasses.fields(cls.Config)}
    unknown = sorted(set(params) - fields)
    if unknown:
        raise TypeError(f"Unknown parameter(s) {unknown} for codec {name!r}; its config fields are {sorted(fields)}.")
    params = {key: tuple(value) if isinstance(value, list) else value for key, value in params.items()}
    return cls(cls.Config(**params))
