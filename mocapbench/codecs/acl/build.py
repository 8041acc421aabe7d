"""Find ACL's headers and the C++ compiler, and build (once, cached) the shim that the ``acl`` codec loads.

ACL 2.1 and its math library rtm are header-only C++. The folder holding them is a setting:

1. the ``acl_dir`` field of the codec's config (``codec.acl_dir=...`` in Hydra), if not empty;
2. else ``$MOCAPBENCH_ACL_DIR``;
3. else ``../shared/third_party/acl-2.1.0`` relative to the working directory, then to the repository root
   (the folder holding ``mocapbench/``), then beside ``$MOCAPBENCH_CMU_DIR`` (``<shared>/data/cmu`` ->
   ``<shared>/third_party/acl-2.1.0``: the shared folder holds both).

Two layouts are accepted: the one of ``../shared`` (``acl/includes`` and ``rtm/includes`` side by side) and a
plain clone of nfrechette/acl v2.1.0 with rtm in ``external/rtm`` (``includes`` and ``external/rtm/includes``).

The shim (``shim.cpp`` beside this module) is compiled with the system C++ compiler (``$CXX``, else ``g++``,
else ``c++``) into ``~/.cache/mocapbench/acl-<hash>/`` (``$MOCAPBENCH_CACHE_DIR`` or ``$XDG_CACHE_HOME``
override the root), where the hash covers the shim's source, the resolved ACL folder and the compiler's
path and version: editing the shim or pointing at another ACL builds anew. The cache, its lock and the atomic
rename are :mod:`mocapbench.codecs.native_build`'s (shared with ``mcb-rot``'s runtime). Nothing here runs at
import time: :func:`quick_check` only looks for the folder and the compiler (used by the registry),
:func:`build_shim` compiles on first use.
"""

from __future__ import annotations

import os
import platform
from dataclasses import dataclass
from pathlib import Path

from mocapbench.codecs.native_build import build_library, cache_root, compiler_version, find_program

__all__ = [
    "ACL_DIR_ENV",
    "AclSetupError",
    "AclHeaders",
    "find_acl_headers",
    "find_compiler",
    "quick_check",
    "build_shim",
    "cache_root",
]

ACL_DIR_ENV = "MOCAPBENCH_ACL_DIR"
_DEFAULT_RELATIVE = Path("..") / "shared" / "third_party" / "acl-2.1.0"
_SHIM_SOURCE = Path(__file__).with_name("shim.cpp")
_HOW_TO_GET = (
    "clone nfrechette/acl at v2.1.0 (with its rtm submodule) and set $MOCAPBENCH_ACL_DIR or codec.acl_dir to it"
)


class AclSetupError(RuntimeError):
    """ACL's headers or a C++ compiler is missing, or the shim does not compile; the message says which."""


@dataclass(frozen=True)
class AclHeaders:
    """The resolved ACL folder and its two include directories."""

    root: Path
    acl_include: Path
    rtm_include: Path


def _candidates(acl_dir: str | os.PathLike | None) -> list[tuple[Path, str]]:
    if acl_dir:
        return [(Path(acl_dir).expanduser(), "codec.acl_dir")]
    if os.environ.get(ACL_DIR_ENV):
        return [(Path(os.environ[ACL_DIR_ENV]).expanduser(), f"${ACL_DIR_ENV}")]
    repo_root = Path(__file__).resolve().parents[3]
    candidates = [
        (Path.cwd() / _DEFAULT_RELATIVE, "the working directory"),
        (repo_root / _DEFAULT_RELATIVE, "the repository root"),
    ]
    cmu_dir = os.environ.get("MOCAPBENCH_CMU_DIR")
    if cmu_dir:  # the shared folder that holds data/cmu also holds third_party/
        candidates.append((Path(cmu_dir).expanduser() / ".." / ".." / "third_party" / "acl-2.1.0", "beside $MOCAPBENCH_CMU_DIR"))
    return candidates


def _layout(root: Path) -> AclHeaders | None:
    for acl_include, rtm_include in (
        (root / "acl" / "includes", root / "rtm" / "includes"),
        (root / "includes", root / "external" / "rtm" / "includes"),
    ):
        if (acl_include / "acl" / "compression" / "compress.h").is_file() and (rtm_include / "rtm" / "qvvf.h").is_file():
            return AclHeaders(root.resolve(), acl_include.resolve(), rtm_include.resolve())
    return None


def find_acl_headers(acl_dir: str | os.PathLike | None = None) -> AclHeaders:
    """The ACL + rtm headers to compile against (see the module docstring for the search order).

    Raises
    ------
    AclSetupError
        No candidate folder holds ``acl/compression/compress.h`` and ``rtm/qvvf.h``; the message lists where it
        looked and how to get ACL.
    """
    candidates = _candidates(acl_dir)
    for candidate, _ in candidates:
        headers = _layout(candidate)
        if headers is not None:
            return headers
    looked = "; ".join(f"{path} (from {source})" for path, source in candidates)
    raise AclSetupError(f"ACL 2.1 headers not found (acl/includes + rtm/includes); looked in {looked}: {_HOW_TO_GET}")


def find_compiler() -> str:
    """Path of the C++ compiler: ``$CXX``, else ``g++``, else ``c++``; :class:`AclSetupError` if none."""
    path = find_program((os.environ.get("CXX"), "g++", "c++"))
    if path is not None:
        return path
    raise AclSetupError("no C++ compiler found (set $CXX or install g++, e.g. `apt-get install g++`)")


def quick_check(acl_dir: str | os.PathLike | None = None) -> str | None:
    """Cheap availability check (no compile): ``None`` if ACL and a compiler are there, else the one-line reason."""
    try:
        find_acl_headers(acl_dir)
        find_compiler()
    except AclSetupError as error:
        return str(error)
    return None


def _compile_flags() -> list[str]:
    flags = ["-std=c++17", "-O2", "-DNDEBUG", "-fPIC", "-shared", "-fvisibility=hidden"]
    if platform.machine().lower() in ("x86_64", "amd64"):
        flags.append("-msse4.1")  # ACL's documented minimum for x86-64 (SOURCE.md)
    return flags


def _compiler_version(compiler: str) -> str:
    try:
        return compiler_version(compiler)
    except OSError as error:
        raise AclSetupError(f"cannot run the C++ compiler {compiler}: {error}") from error


def build_shim(acl_dir: str | os.PathLike | None = None) -> Path:
    """The compiled shim for this ACL folder, building it if the cache lacks it.

    Returns
    -------
    Path
        The shared library (``libmcb_acl.so``) in its cache folder.

    Raises
    ------
    AclSetupError
        Headers or compiler missing, or the compile failed (the message holds the compiler's first error line
        and the log's path).
    """
    headers = find_acl_headers(acl_dir)
    compiler = find_compiler()
    parts = (_SHIM_SOURCE.read_bytes(), str(headers.acl_include).encode(), str(headers.rtm_include).encode(),
             compiler.encode(), _compiler_version(compiler).encode(), " ".join(_compile_flags()).encode())
    library = build_library(
        "acl", "libmcb_acl.so", parts,
        lambda output: [compiler, *_compile_flags(), "-I", str(headers.acl_include), "-I", str(headers.rtm_include),
                        str(_SHIM_SOURCE), "-o", output],
        AclSetupError, f"the ACL shim against {headers.root}")
    source = library.parent / "source.txt"
    if not source.is_file():
        source.write_text(f"ACL folder: {headers.root}\ncompiler: {compiler}\n")
    return library
