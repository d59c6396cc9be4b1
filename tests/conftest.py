"""Suite-wide checks (every FMU gatetwin writes during the tests has well-formed XML) and the
fixtures several test modules share, built once per session."""

from __future__ import annotations

import pytest

import build_cache
from fmu_support import compiler, export_all, gatetwin_fmus, model_description_problem


@pytest.fixture(scope="session", autouse=True)
def compiled_binaries_are_reused():
    """The session's FMU binaries come from :mod:`build_cache` where the same build was made
    before (same compiler, flags and sources, byte for byte)."""
    if not build_cache.available():
        yield
        return
    from gatetwin.fmu import c_build

    build_cache.prune()
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(c_build, "compile_shared", build_cache.cached(c_build))
        yield


@pytest.fixture(scope="session", autouse=True)
def every_written_model_description_is_well_formed(tmp_path_factory):
    """After the session, parse the modelDescription.xml of every FMU gatetwin wrote under
    the session's temporary folders; a malformed one fails the session's last test."""
    yield
    problems = [
        f"{path}: {why}"
        for path in gatetwin_fmus(tmp_path_factory.getbasetemp())
        if (why := model_description_problem(path))
    ]
    assert not problems, "\n".join(problems)


@pytest.fixture(scope="session")
def test_plant_fmus(tmp_path_factory):
    """Every (backend, family) FMU of the test plants (:func:`fmu_support.export_all`), built
    once for the modules that only read them; skips without a C compiler."""
    if compiler() is None:
        pytest.skip("no C compiler (cc/gcc) on PATH")
    return export_all(tmp_path_factory.mktemp("test_plant_fmus"))
