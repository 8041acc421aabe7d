"""``mcb-rot``: mocapbench's rotation codec with a guaranteed joint-position bound (a design of this project).

The stream codes what an engine plays back (each joint's local rotation, the root translation, the skeleton) and
the encoder guarantees that forward kinematics of the decoded motion puts every joint and end site within ε:
a base layer (segment DCTs of rotation vectors on each joint's principal axes, quantized with steps drawn from the
lever arms of the hierarchy), then a closed loop of corrections until nothing misses the bound.

Modules
-------
codec
    The registered codec: settings, the rate search and the encoder and decoder entry points.
stream
    The payload: its header, its chunks, and the path from bytes to rotations.
quaternions
    Unit-quaternion arithmetic shared by encoder and decoder.
axes
    Per-joint principal axes: each joint's rotation-vector channels turned onto its axes of motion.
budgets
    How much rotation error each joint may carry: lever arms down the hierarchy.
segments
    Where segments start (a fixed grid, restarted at every cut) and their DCTs.
compensate
    Quantizing the base layer, optionally with each joint compensating its ancestors' errors.
classes
    The per-stream adaptive entropy model: parametric token distributions chosen by the encoder.
rate
    The payload size estimated without entropy coding: what the rate search ranks.
checks
    What the encoder checks on every frame: joint, end-site and shell-vertex errors.
refine
    The encoder's closed loop: corrections until every joint is within the bound.
tracks
    A game rig's translation tracks (payload format 6).
scales
    A game rig's scale tracks (format 6, settings flag bit 13).
static_root
    A game rig's still ground root kept apart, its moving pelvis coded as the root (payload format 6).
skeleton6
    The skeleton of a format 6 stream, in bits a native sampler can read.
decoder
    The numpy decoder: chunks read a block at a time into preallocated outputs.
scratch
    The decoder's work arrays, reused from block to block.
kinematics
    Forward kinematics on quaternions, the decoder's hot loop (numba).
native
    The native C runtime from Python: built on first use, loaded with ctypes.
prior
    A prior of the training clips' rigs (settings flag bit 15): a known rig named instead of carried.
windowed
    Long captures coded as independent windows (bounded memory).
"""

from mocapbench.codecs.mcb_rot.codec import McbRotCodec

__all__ = ["McbRotCodec"]
