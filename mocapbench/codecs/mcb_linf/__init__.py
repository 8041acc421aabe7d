"""``mcb-linf``: mocapbench's position codec with a guaranteed L-inf joint error (a design of this project).

Modules
-------
codec
    The registered codec: the stream format, the bound's refinement, the encoder and decoder.
layers
    The signal layers: representations, the clip DCT and its coefficient layout, steps, lattice.
model
    What the codec learns from training motions (PCA basis, trained entropy model) and the shipped model.
"""

from mocapbench.codecs.mcb_linf.codec import McbLinfCodec

__all__ = ["McbLinfCodec"]
