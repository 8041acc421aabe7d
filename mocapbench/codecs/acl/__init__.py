"""The ``acl`` codec: ACL 2.1 (the Animation Compression Library) through a small C++ shim.

Importing this package compiles nothing: it only checks that ACL's headers and a C++ compiler are there
(:func:`build.quick_check`) and registers :class:`AclCodec`, or lists ``acl`` as unavailable with the one line
saying what is missing. The shim is compiled on first use (:mod:`mocapbench.codecs.acl.build`).

Modules
-------
codec
    The registered codec: each joint one ACL transform track, the stream around ACL's compressed clip.
build
    Finding ACL's headers and the C++ compiler, and building the shim (once, cached).
binding
    ctypes calls into the compiled shim, its failures raised as one line.
"""

from mocapbench.codecs.acl.build import quick_check
from mocapbench.codecs.acl.codec import AclCodec
from mocapbench.codecs.registry import register_codec, register_unavailable

__all__ = ["AclCodec"]

_MISSING = quick_check()
if _MISSING is None:
    register_codec(AclCodec)
else:
    register_unavailable(AclCodec.name, _MISSING)
