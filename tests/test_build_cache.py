"""The tests' build cache (:mod:`build_cache`) reuses a binary only for the same build."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pytest

import build_cache


def test_a_build_is_reused_only_while_compiler_flags_and_every_source_byte_are_the_same(
        tmp_path, monkeypatch):  # fmt: skip
    if not build_cache.available():
        pytest.skip("no fcntl here: nothing is cached")
    monkeypatch.setattr(build_cache, "FOLDER", tmp_path / "cache")
    built: list[tuple[str, ...]] = []

    def compile_shared(sources, c_files, out, extra_flags=(), compiler=None):
        built.append((*compiler, *extra_flags))
        Path(out).write_bytes(b"binary %d" % len(built))

    sources = tmp_path / "src"
    sources.mkdir()
    (sources / "a.c").write_text('#include "a.h"\n')
    (sources / "a.h").write_text("#define N 1\n")
    c_build = SimpleNamespace(compile_shared=compile_shared, CFLAGS=("-O3",),
                              find_compiler=lambda: ["true"])  # fmt: skip
    compile_cached = build_cache.cached(c_build)
    out = [tmp_path / f"build{k}" / "gate.so" for k in range(6)]  # the name is in the key
    for path in out:
        path.parent.mkdir()
    compile_cached(sources, ("a.c",), out[0])
    compile_cached(sources, ("a.c",), out[1])  # the same build: served
    (sources / "a.h").write_text("#define N 2\n")  # a header byte changes
    compile_cached(sources, ("a.c",), out[2])
    compile_cached(sources, ("a.c",), out[3], ("-DX",))  # another flag
    compile_cached(sources, ("a.c",), out[4], compiler=["false"])  # another compiler
    compile_cached(sources, ("a.c",), out[5], ("-DX",))  # served again
    assert len(built) == 4
    contents = [p.read_bytes() for p in out]
    assert contents[1] == contents[0] and contents[5] == contents[3]
    assert len({contents[0], contents[2], contents[3], contents[4]}) == 4
