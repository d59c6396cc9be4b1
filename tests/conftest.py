"""Suite-wide checks: every FMU gatetwin writes during the tests has well-formed XML."""

from __future__ import annotations

import pytest

from fmu_support import gatetwin_fmus, model_description_problem


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
