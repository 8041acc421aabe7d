"""The types of the glTF fields mocapbench reads, checked on the JSON before anything uses them.

``pygltflib`` turns JSON objects into dataclasses but keeps every value as the JSON gave it: a node's
``rotation`` may arrive as three numbers or a string, an accessor's ``byteOffset`` as -1 or 1e308, a sampler as
``null``. Each would fail later as a ``TypeError`` or a numpy broadcast error far from its cause. This module walks
the fields the reader uses (nodes, skins, animations, accessors, buffer views, buffers, images; glTF 2.0 section
5) and refuses, in one line naming the field (``nodes[3].rotation``), any value of the wrong JSON type, arity or
range: indices and sizes are integers >= 0, vectors have their length of finite numbers, names and enums are
strings. Fields it does not read (materials, meshes' attributes, extensions) are left to ``pygltflib``.
"""

from __future__ import annotations

import math
from collections.abc import Callable

__all__ = ["check_document"]

_Error = Callable[[str], Exception]
_INDEX, _SIZE, _STRING, _BOOL, _OBJECT = "index", "size", "string", "bool", "object"
# Top-level arrays and, for each of their objects, the fields read: kind, or ("numbers", length) / ("indices",).
_FIELDS: dict[str, dict[str, object]] = {
    "nodes": {"children": ("indices",), "rotation": ("numbers", 4), "translation": ("numbers", 3),
              "scale": ("numbers", 3), "matrix": ("numbers", 16), "name": _STRING, "mesh": _INDEX, "skin": _INDEX},
    "skins": {"joints": ("indices",), "skeleton": _INDEX, "inverseBindMatrices": _INDEX, "name": _STRING},
    "animations": {"channels": ("objects",), "samplers": ("objects",), "name": _STRING},
    "accessors": {"bufferView": _INDEX, "byteOffset": _SIZE, "count": _SIZE, "componentType": _SIZE,
                  "type": _STRING, "normalized": _BOOL, "sparse": _OBJECT},
    "bufferViews": {"buffer": _INDEX, "byteOffset": _SIZE, "byteLength": _SIZE, "byteStride": _SIZE},
    "buffers": {"byteLength": _SIZE, "uri": _STRING},
    "images": {"uri": _STRING},
    "scenes": {"nodes": ("indices",)},
}
_CHANNEL = {"sampler": _INDEX, "target": _OBJECT}
_TARGET = {"node": _INDEX, "path": _STRING}
_SAMPLER = {"input": _INDEX, "output": _INDEX, "interpolation": _STRING}
_ASSET = {"version": _STRING}


def check_document(document: object, error: _Error) -> None:
    """Refuse a glTF JSON document whose read fields have the wrong type (see the module docstring).

    Parameters
    ----------
    document : object
        The parsed JSON.
    error : callable
        One-line message -> exception.
    """
    if not isinstance(document, dict):
        raise error(f"expected a JSON object as the glTF document, got a JSON {_json_type(document)}")
    _check_object(document.get("asset"), _ASSET, "asset", error, required=True)
    for name, fields in _FIELDS.items():
        items = document.get(name)
        if items is None:
            continue
        if not isinstance(items, list):
            raise error(f"{name} must be a JSON array, got a JSON {_json_type(items)}")
        for index, item in enumerate(items):
            where = f"{name}[{index}]"
            _check_object(item, fields, where, error, required=True)
            if name == "animations":
                for c, channel in enumerate(item.get("channels") or []):
                    _check_object(channel, _CHANNEL, f"{where}.channels[{c}]", error, required=True)
                    _check_object(channel.get("target"), _TARGET, f"{where}.channels[{c}].target", error,
                                  required=True)
                for s, sampler in enumerate(item.get("samplers") or []):
                    _check_object(sampler, _SAMPLER, f"{where}.samplers[{s}]", error, required=True)


def _check_object(item: object, fields: dict[str, object], where: str, error: _Error, *, required: bool) -> None:
    if item is None and not required:
        return
    if not isinstance(item, dict):
        raise error(f"{where} must be a JSON object, got a JSON {_json_type(item)}")
    for key, kind in fields.items():
        value = item.get(key)
        if value is not None:
            _check_value(value, kind, f"{where}.{key}", error)


def _check_value(value: object, kind: object, where: str, error: _Error) -> None:
    if kind in (_INDEX, _SIZE, _STRING, _BOOL, _OBJECT):
        _check_single(value, kind, where, error)
    else:
        _check_array(value, kind, where, error)


def _check_single(value: object, kind: str, where: str, error: _Error) -> None:
    """A value of one of the single kinds: an index or size, a string, a boolean, an object."""
    if kind in (_INDEX, _SIZE):
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise error(f"{where} must be an integer >= 0, got {_shown(value)}")
    elif kind == _STRING:
        if not isinstance(value, str):
            raise error(f"{where} must be a string, got a JSON {_json_type(value)}")
    elif kind == _BOOL:
        if not isinstance(value, bool):
            raise error(f"{where} must be true or false, got {_shown(value)}")
    elif kind == _OBJECT:
        if not isinstance(value, dict):
            raise error(f"{where} must be a JSON object, got a JSON {_json_type(value)}")


def _check_array(value: object, kind: tuple, where: str, error: _Error) -> None:
    """A value of one of the array kinds: ``("numbers", length)``, ``("indices",)``, ``("objects",)``."""
    if kind[0] == "numbers":
        length = kind[1]
        if (not isinstance(value, list) or len(value) != length
                or not all(_finite_number(v) for v in value)):
            raise error(f"{where} must be {length} finite numbers, got {_shown(value)}")
    elif kind[0] == "indices":
        if not isinstance(value, list) or not all(isinstance(v, int) and not isinstance(v, bool) and v >= 0
                                                  for v in value):
            raise error(f"{where} must be an array of integers >= 0, got {_shown(value)}")
    elif kind[0] == "objects":
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            raise error(f"{where} must be an array of JSON objects, got {_shown(value)}")


def _finite_number(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _json_type(value: object) -> str:
    return {dict: "object", list: "array", str: "string", bool: "boolean", type(None): "null"}.get(
        type(value), "number")


def _shown(value: object) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."
