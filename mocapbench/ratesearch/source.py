"""The clip a rate search codes, with its forward kinematics computed once (every try reads the same source).

A rate search encodes one clip a dozen times, and every try's encoder, every try's error measure and the final
evaluation read the clip's global positions (and the evaluation its global transforms, for end sites and ACL's
shell error): forward kinematics of the very same frames, once per try. :func:`known_kinematics` returns the clip
as a :class:`Motion` (same arrays, not copied) whose :meth:`~Motion.positions` and :meth:`~Motion.global_transforms`
run forward kinematics on the first call only and hand out copies of that result afterwards: the same values, so
the same streams and the same errors, for the cost of a copy.

A motion derived from it (``dataclasses.replace``, :meth:`~Motion.slice`, :meth:`~Motion.every`) is a new motion
and computes its own kinematics. The result is kept only as long as the returned motion lives (one clip's search);
the global transforms (three times the positions' memory) are kept only once something asked for them.
"""

from __future__ import annotations

import numpy as np

from mocapbench.motion import Motion

__all__ = ["known_kinematics"]


class _KnownKinematics(Motion):
    """A :class:`Motion` whose forward kinematics is computed once (see the module docstring)."""

    def positions(self) -> np.ndarray:
        known = self.__dict__.get("_known_positions")
        if known is None:
            transforms = self.__dict__.get("_known_transforms")
            known = transforms[1] if transforms is not None else super().positions()
            object.__setattr__(self, "_known_positions", known)
        return known.copy()

    def global_transforms(self) -> tuple[np.ndarray, np.ndarray]:
        known = self.__dict__.get("_known_transforms")
        if known is None:
            known = super().global_transforms()
            object.__setattr__(self, "_known_transforms", known)
        return known[0].copy(), known[1].copy()


def known_kinematics(motion: Motion) -> Motion:
    """``motion`` with its forward kinematics computed once (returned as is when it already is such a motion).

    Parameters
    ----------
    motion : Motion

    Returns
    -------
    Motion
        The same clip (the same arrays, shared): :meth:`~Motion.positions` (F, J, 3) float, cm, and
        :meth:`~Motion.global_transforms` give the values ``motion``'s would, computed on their first call.
    """
    if type(motion) is _KnownKinematics:
        return motion
    if type(motion) is not Motion:  # a subclass may compute its kinematics its own way: leave it alone
        return motion
    known = object.__new__(_KnownKinematics)
    known.__dict__.update(motion.__dict__)  # the validated fields as they are: no second construction
    return known
