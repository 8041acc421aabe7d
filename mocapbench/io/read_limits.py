"""How large a motion a reader may build: frames × joints checked against the decode limits before allocating.

A motion file states (or implies) its size before its arrays exist: a BVH header says ``Frames: N``, a glTF or
FBX animation's last key time at a sampling rate gives N frames, its skeleton J joints. A few kB of such a file
can ask for gigabytes (a 59 kB glTF whose last key sits at 80,000 s), so every reader checks F and J, and the
arrays they imply, against the same :class:`~mocapbench.codecs.limits.DecodeLimits` a decoder honours:

* ``max_frames`` and ``max_joints``;
* ``max_output_bytes`` against :func:`~mocapbench.codecs.limits.output_bytes` of F and J with rotations (float64
  positions, quaternions and root positions): what the resulting :class:`~mocapbench.motion.Motion` holds. A
  reader's own temporaries are a bounded multiple of it.

The limits are the current ones (:func:`~mocapbench.codecs.limits.using_limits`), so ``--limit`` raises them for
a trusted large capture, for reading as for decoding.
"""

from __future__ import annotations

from collections.abc import Callable

__all__ = ["check_array_bytes", "check_motion_size"]


def check_motion_size(num_frames: int, num_joints: int, error: Callable[[str], Exception], what: str = "") -> None:
    """Refuse a motion of ``num_frames`` × ``num_joints`` that exceeds the current limits, before allocating it.

    Parameters
    ----------
    num_frames, num_joints : int
        F and J the reader is about to allocate for.
    error : callable
        The reader's error factory: a one-line message (no file name, no final period) -> the exception to
        raise (e.g. ``lambda message: MotionFormatError(f"{path}: {message}.")``).
    what : str, optional
        Where the size comes from (``"at 120 fps"``), appended to the message.

    Raises
    ------
    Exception
        ``error(message)`` naming the limit, the value asked for, the value allowed and the ``--limit`` to raise.
    """
    # Imported here, so that importing io does not import the codecs package (its __init__ fills the registry);
    # reading a file does.
    from mocapbench.codecs.limits import current_limits, output_bytes

    limits = current_limits()
    detail = f" {what}" if what else ""
    size = output_bytes(num_frames, num_joints, True)
    for limit, value, asked in (
        ("max_frames", num_frames, f"{num_frames:,} frames{detail}"),
        ("max_joints", num_joints, f"{num_joints:,} joints"),
        ("max_output_bytes", size, f"{num_frames:,} frames{detail} x {num_joints:,} joints, {size:,} bytes of arrays"),
    ):
        allowed = getattr(limits, limit)
        if value > allowed:
            short = limit.removeprefix("max_")
            raise error(
                f"the file asks for {asked}, over the limit {short}={allowed:,}; raise it with --limit {short}=N "
                f"if the file is trusted"
            )


def check_array_bytes(num_bytes: int, error: Callable[[str], Exception], what: str) -> None:
    """Refuse an intermediate array of ``num_bytes`` (e.g. an accessor's float64 copy) over ``max_output_bytes``.

    Raises ``error(message)`` naming ``what``, its size and the limit.
    """
    from mocapbench.codecs.limits import current_limits

    allowed = current_limits().max_output_bytes
    if num_bytes > allowed:
        raise error(
            f"{what} needs {num_bytes:,} bytes, over the limit output_bytes={allowed:,}; raise it with "
            f"--limit output_bytes=N if the file is trusted"
        )
