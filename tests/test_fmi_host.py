"""The FMU host: a file that is not an FMU is refused in one line and leaves nothing unpacked."""

from __future__ import annotations

import tempfile
import zipfile

import pytest

from gatetwin.errors import ControlError, GatetwinError
from gatetwin.fmi_host import UnpackedFmu
from gatetwin.mpc.fmu_controller import FmuController
from gatetwin.mpc.plants import FmuCore


@pytest.fixture
def temp_root(tmp_path, monkeypatch):
    """The folder temporary folders are made in (fmpy unpacks FMUs into one), empty."""
    root = tmp_path / "tmp"
    root.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(root))
    return root


def _zip(path, members):
    with zipfile.ZipFile(path, "w") as archive:
        for name, text in members.items():
            archive.writestr(name, text)
    return path


@pytest.mark.parametrize("opener", [UnpackedFmu, FmuController, FmuCore])
def test_a_file_that_is_not_a_zip_archive_is_refused_naming_it(opener, tmp_path, temp_root):
    path = tmp_path / "plant.fmu"
    path.write_text("not an archive\n")
    refusal = r"plant\.fmu is not an FMU: not a readable zip"
    with pytest.raises(GatetwinError, match=refusal) as info:
        opener(path)
    assert "\n" not in str(info.value)
    assert list(temp_root.iterdir()) == []


@pytest.mark.parametrize("opener", [FmuController, FmuCore])
def test_an_archive_without_a_model_description_is_refused_and_removed(opener, tmp_path,
                                                                        temp_root):  # fmt: skip
    path = _zip(tmp_path / "plant.fmu", {"binaries/readme.txt": "nothing here"})
    with pytest.raises(ControlError, match=r"plant\.fmu is not an FMU: not unpacked, or no model"):
        opener(path)
    assert list(temp_root.iterdir()) == []


def test_a_missing_file_is_refused_naming_it(tmp_path, temp_root):
    with pytest.raises(ControlError, match=r"absent\.fmu: no such file; expected an FMU"):
        UnpackedFmu(tmp_path / "absent.fmu", error=ControlError)
    assert list(temp_root.iterdir()) == []


@pytest.mark.parametrize(("member", "why"), [("resources\\..\\..\\a.txt", "climbs out"),
                                             ("/etc/a.txt", "absolute path"),
                                             ("C:\\a.txt", "absolute path")])  # fmt: skip
def test_a_member_that_would_land_outside_is_refused_before_unpacking(member, why, tmp_path,
                                                                      temp_root):  # fmt: skip
    path = _zip(tmp_path / "plant.fmu", {"modelDescription.xml": "<x/>", member: "x"})
    with pytest.raises(ControlError, match=rf"plant\.fmu: refused: the archive member .*{why}"):
        FmuController(path)
    assert list(temp_root.iterdir()) == []


def test_a_member_fmpy_refuses_to_unpack_leaves_nothing(tmp_path, temp_root):
    # a backslash in a member name: fmpy's extract makes its folder, then raises
    path = _zip(tmp_path / "plant.fmu", {"modelDescription.xml": "<x/>", "resources\\a.txt": "x"})
    with pytest.raises(ControlError, match=r"plant\.fmu is not an FMU: not unpacked"):
        FmuCore(path)
    assert list(temp_root.iterdir()) == []
