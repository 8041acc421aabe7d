"""The shared build cache of native libraries: one compile per key, the caller's error on a failed compile."""

from __future__ import annotations

import os

import pytest

from mocapbench.codecs import native_build


@pytest.fixture
def compiler():
    found = native_build.find_program(["cc", "gcc", "clang"])
    if found is None:
        if os.environ.get("CI", "").strip().lower() in ("true", "1"):  # CI installs a compiler: a missing one there is a failure, not a skip
            pytest.fail("no C compiler (cc, gcc or clang) on the PATH")
        pytest.skip("no C compiler (CI=true makes this a failure)")
    return found


def _build(tmp_path, compiler, text: str):
    source = tmp_path / "tiny.c"
    source.write_text(text)
    calls = []

    def command(output: str) -> list[str]:
        calls.append(output)
        return [compiler, "-shared", "-fPIC", str(source), "-o", output]

    path = native_build.build_library("tiny", "libtiny.so", [source.read_bytes()], command, ValueError, "the tiny")
    return path, calls


def test_a_library_is_compiled_once_per_key_and_kept(tmp_path, monkeypatch, compiler):
    monkeypatch.setenv("MOCAPBENCH_CACHE_DIR", str(tmp_path / "cache"))
    first, calls = _build(tmp_path, compiler, "int tiny(void) { return 1; }\n")
    again, calls_again = _build(tmp_path, compiler, "int tiny(void) { return 1; }\n")
    other, _ = _build(tmp_path, compiler, "int tiny(void) { return 2; }\n")
    assert first == again and first.is_file() and len(calls) == 1 and calls_again == []
    assert other != first  # the key covers the source
    assert not list((tmp_path / "cache").glob("*/*.partial"))
    assert (first.parent / "build.log").read_text().startswith(compiler)


def test_a_failed_compile_raises_the_callers_error_in_one_line(tmp_path, monkeypatch, compiler):
    monkeypatch.setenv("MOCAPBENCH_CACHE_DIR", str(tmp_path / "cache"))
    with pytest.raises(ValueError, match="compiling the tiny failed: .*error.*build.log") as caught:
        _build(tmp_path, compiler, "int tiny(void) { return }\n")
    assert "\n" not in str(caught.value)
    assert not list((tmp_path / "cache").glob("*/*.so"))
