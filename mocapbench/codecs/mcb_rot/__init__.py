"""``mcb-rot``: mocapbench's rotation codec with a guaranteed joint-position bound (see :mod:`.codec`).

Modules, one job each: :mod:`.quaternions` (rotation arithmetic), :mod:`.budgets` (error budgets from lever arms),
:mod:`.segments` (cuts, segments, DCT), :mod:`.classes` (per-stream adaptive entropy model), :mod:`.codec` (the codec).
"""

from mocapbench.codecs.mcb_rot.codec import McbRotCodec

__all__ = ["McbRotCodec"]
