"""Heavy third-party names imported on first use, so that ``mocapbench codecs`` and ``--help`` start fast.

Importing every codec module (which the registry does) used to import ``scipy.spatial`` (k-d trees, qhull,
``scipy.sparse``, ``scipy.linalg``: about 0.3 s of CPU) although listing codecs never rotates anything. Modules
therefore take :data:`Rotation` from here instead of ``scipy.spatial.transform``; it is a stand-in that imports the
real class the first time it is called, an attribute is read (``Rotation.from_quat``) or it is used in
``isinstance``. ``scipy.fft`` needs no stand-in: ``import scipy`` is cheap and ``scipy.fft`` loads on first access.

Torch, pandas, matplotlib and Hydra are imported inside the functions that use them (see :mod:`mocapbench.cli`).
"""

from __future__ import annotations

import importlib
from typing import Any

__all__ = ["Lazy", "Rotation", "pywt"]


class Lazy:
    """A module, or one name in a module, imported the first time it is used.

    Parameters
    ----------
    module : str
        Dotted module name, e.g. ``"scipy.spatial.transform"``.
    name : str, optional
        A name in that module (e.g. ``"Rotation"``); default: the module itself.

    Attribute access, calls, ``isinstance``/``issubclass`` and ``repr`` are forwarded to the real object; the
    import happens once and the object is cached.
    """

    __slots__ = ("_module", "_name", "_target")

    def __init__(self, module: str, name: str | None = None) -> None:
        self._module = module
        self._name = name
        self._target: Any = None

    def resolve(self) -> Any:
        """The real module or object (imported now if it was not yet)."""
        if self._target is None:
            module = importlib.import_module(self._module)
            self._target = module if self._name is None else getattr(module, self._name)
        return self._target

    def __getattr__(self, attribute: str) -> Any:
        return getattr(self.resolve(), attribute)

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        return self.resolve()(*args, **kwargs)

    def __instancecheck__(self, instance: Any) -> bool:
        return isinstance(instance, self.resolve())

    def __subclasscheck__(self, subclass: type) -> bool:
        return issubclass(subclass, self.resolve())

    def __repr__(self) -> str:
        state = "imported" if self._target is not None else "not imported yet"
        target = self._module if self._name is None else f"{self._module}.{self._name}"
        return f"<lazy {target} ({state})>"


Rotation = Lazy("scipy.spatial.transform", "Rotation")
"""Stand-in for :class:`scipy.spatial.transform.Rotation` (see the module docstring)."""

pywt = Lazy("pywt")
"""Stand-in for the ``pywt`` (PyWavelets) module."""
