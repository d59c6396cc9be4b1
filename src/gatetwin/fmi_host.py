"""Open an extracted FMI 2.0 or 3.0 co-simulation FMU through fmpy, with its log kept.

:func:`open_instance` loads the binary, instantiates it with a logger that keeps the FMU's
messages (instead of fmpy's default, which prints them) and returns an :class:`Instance`
with the FMI 2.0 verbs whatever the version (for FMI 3.0: ``setupExperiment`` keeps the
start time for ``fmi3EnterInitializationMode``, get/set Real are get/set Float64, ``doStep``
asks for no early return). :func:`unpack_fmu` unpacks an FMU file after checking its
archive (size, members inside the folder); :class:`UnpackedFmu` is an FMU file unpacked
into a folder of its own, its model description read, its one instance opened, closed and
the folder deleted there. The validation harness, the SSP master, the observer's reference
run and the closed loop's FMU plant and controller all unpack and open FMUs here.
"""

from __future__ import annotations

import contextlib
import os
import shutil
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gatetwin.errors import GatetwinError

__all__ = ["Instance", "UnpackedFmu", "open_instance", "unpack_fmu"]


@dataclass(eq=False)
class Instance:
    """One instantiated FMU: its fmpy slave behind the FMI 2.0 verbs, and its log."""

    slave: Any
    fmi3: bool
    messages: list[tuple[int, str]] = field(default_factory=list)
    callbacks: Any = None  # the ctypes callbacks, alive as long as the instance
    start_time_s: float = 0.0

    def log(self, status: int, message: bytes) -> None:
        self.messages.append((int(status), message.decode("utf-8", "replace")))

    def last_problem(self) -> str:
        """The FMU's last logged message of status warning or worse ("" if none)."""
        bad = [text for status, text in self.messages if status >= 1]
        return " ".join(bad[-1].split()) if bad else ""

    def setupExperiment(self, startTime: float) -> None:  # noqa: N802, N803 (fmpy's names)
        if self.fmi3:
            self.start_time_s = startTime
        else:
            self.slave.setupExperiment(startTime=startTime)

    def enterInitializationMode(self) -> None:  # noqa: N802
        if self.fmi3:
            self.slave.enterInitializationMode(startTime=self.start_time_s)
        else:
            self.slave.enterInitializationMode()

    def exitInitializationMode(self) -> None:  # noqa: N802
        self.slave.exitInitializationMode()

    def getReal(self, vr: list[int]) -> list[float]:  # noqa: N802
        return (self.slave.getFloat64 if self.fmi3 else self.slave.getReal)(vr)

    def setReal(self, vr: list[int], values: list[float]) -> None:  # noqa: N802
        (self.slave.setFloat64 if self.fmi3 else self.slave.setReal)(vr, values)

    def doStep(self, currentCommunicationPoint: float, communicationStepSize: float  # noqa: N802, N803
               ) -> None:  # fmt: skip
        self.slave.doStep(currentCommunicationPoint, communicationStepSize)

    def terminate(self) -> None:
        self.slave.terminate()

    def freeInstance(self) -> None:  # noqa: N802
        self.slave.freeInstance()

    def initialise(self, start_time_s: float, *settings: tuple[list[int], list[float]]) -> None:
        """Set up the experiment at ``start_time_s``, enter initialisation mode, make each
        ``(value references, values)`` setReal call of ``settings`` in order, and leave it."""
        self.setupExperiment(startTime=start_time_s)
        self.enterInitializationMode()
        for vrs, values in settings:
            self.setReal(list(vrs), [float(v) for v in values])
        self.exitInitializationMode()

    def close(self) -> None:
        """Terminate (its refusal ignored: an instance a refused call left in error cannot
        terminate) and free."""
        from fmpy.fmi1 import FMICallException

        with contextlib.suppress(FMICallException):
            self.terminate()
        self.freeInstance()


def open_instance(md: Any, unzip_dir: str, instance_name: str, *, what: str,
                  error: type[GatetwinError] = GatetwinError, logging_on: bool = True,
                  loaded: Callable[[], None] | None = None) -> Instance:  # fmt: skip
    """Load and instantiate the FMU extracted to ``unzip_dir``, whose model description (an
    fmpy ``ModelDescription``, or anything with its ``fmiVersion``, ``guid`` and
    ``coSimulation.modelIdentifier``) is ``md``. ``loaded`` is called between loading the
    binary and instantiating it (to tell a crash in one from a crash in the other).

    Raises
    ------
    GatetwinError
        (or ``error``) The binary cannot be loaded, or instantiation fails (the FMU's last
        logged problem quoted); ``what`` names the FMU in the message.
    """
    from fmpy.fmi2 import FMU2Slave
    from fmpy.fmi3 import FMU3Slave

    fmi3 = md.fmiVersion.startswith("3.")
    try:
        slave = (FMU3Slave if fmi3 else FMU2Slave)(
            guid=md.guid, unzipDirectory=unzip_dir, instanceName=instance_name,
            modelIdentifier=md.coSimulation.modelIdentifier,
        )  # fmt: skip
    except OSError as exc:
        raise error(f"{what}: the FMU's binary cannot be loaded ({exc})") from None
    if loaded is not None:
        loaded()
    instance = Instance(slave, fmi3)
    try:
        if fmi3:

            def log3(_env: Any, status: int, _category: Any, message: bytes) -> None:
                instance.log(status, message)

            slave.instantiate(loggingOn=logging_on, logMessage=log3)
        else:
            instance.callbacks = _fmi2_callbacks(instance)
            slave.instantiate(callbacks=instance.callbacks, loggingOn=logging_on)
    except Exception:  # fmpy raises a bare Exception when instantiation fails
        slave.freeLibrary()
        detail = instance.last_problem()
        call = "fmi3InstantiateCoSimulation" if fmi3 else "fmi2Instantiate"
        raise error(f"{what}: {call} failed" + (f"; FMU log: {detail}" if detail else "")
                    ) from None  # fmt: skip
    return instance


def unpack_fmu(path: str | os.PathLike[str], folder: str | os.PathLike[str], where: str,
               error: type[GatetwinError] = GatetwinError) -> str:  # fmt: skip
    """Unpack the FMU file ``path`` into ``folder`` (fmpy's ``extract``, from the file opened
    and checked, not from its name again) and return the folder: refused, with ``where``
    naming it, unless it is a regular file holding a zip archive that unpacks to at most
    :data:`gatetwin.records.limits.DEFAULT_MAX_BYTES`, every member inside the folder
    (:func:`gatetwin.records.limits.check_archive`). Every FMU gatetwin runs is unpacked
    here."""
    import sys
    import zipfile

    from fmpy import extract

    from gatetwin.records.limits import check_archive, open_regular

    with open_regular(path, sys.maxsize, "an FMU", error) as handle:
        try:
            with zipfile.ZipFile(handle) as archive:
                check_archive(archive, where, error)
        except GatetwinError:
            raise
        except Exception as exc:  # noqa: BLE001 - zipfile raises several kinds on a bad archive
            raise error(f"{where} is not an FMU: not a readable zip archive ({exc})") from None
        try:
            handle.seek(0)
            return str(extract(handle, folder))
        except Exception as exc:  # noqa: BLE001 - fmpy and zipfile raise plain exceptions
            raise error(f"{where} is not an FMU: not unpacked "
                        f"({' '.join(str(exc).split())[:200]})") from None  # fmt: skip


class UnpackedFmu:
    """The FMU file ``path`` unpacked into a temporary folder of its own, with its model
    description (``description``, fmpy's), its variables and their value references by name
    (``variables``, ``vr``) and at most one open :class:`Instance` (``instance``).

    :meth:`open` (re)instantiates it, :meth:`close` terminates and frees the instance,
    :meth:`cleanup` also deletes the folder.

    Raises
    ------
    GatetwinError
        (or ``error``) The file is not a regular file holding a zip archive, would unpack to
        more than :data:`gatetwin.records.limits.DEFAULT_MAX_BYTES` or outside its folder
        (:func:`gatetwin.records.limits.check_archive`), or holds no model description fmpy
        reads; nothing is left unpacked.
    """

    def __init__(self, path: str | os.PathLike[str], *,
                 error: type[GatetwinError] = GatetwinError) -> None:  # fmt: skip
        import tempfile

        from fmpy import read_model_description

        self.path = Path(path)
        self.error = error
        self.instance: Instance | None = None
        self.folder = tempfile.mkdtemp(prefix="gatetwin-fmu-")
        try:
            unpack_fmu(self.path, self.folder, str(self.path), error)
        except BaseException:
            shutil.rmtree(self.folder, ignore_errors=True)
            raise
        try:
            self.description = read_model_description(self.folder)
        except Exception as exc:  # noqa: BLE001 - fmpy raises plain exceptions on bad FMUs
            shutil.rmtree(self.folder, ignore_errors=True)
            raise error(f"{self.path} is not an FMU: not unpacked, or no model description "
                        f"fmpy reads ({' '.join(str(exc).split())[:200]})") from None  # fmt: skip
        self.variables = {v.name: v for v in self.description.modelVariables}
        self.vr = {name: v.valueReference for name, v in self.variables.items()}

    def open(self, instance_name: str, *, logging_on: bool = False) -> Instance:
        """Close the instance open, if any, and instantiate anew (:func:`open_instance`)."""
        self.close()
        self.instance = open_instance(self.description, self.folder, instance_name,
                                      what=str(self.path), error=self.error,
                                      logging_on=logging_on)  # fmt: skip
        return self.instance

    def close(self) -> None:
        """Terminate and free the open instance (:meth:`Instance.close`), if any."""
        if self.instance is not None:
            instance, self.instance = self.instance, None
            instance.close()

    def cleanup(self) -> None:
        """:meth:`close`, and delete the unpacked folder."""
        try:
            self.close()
        finally:
            shutil.rmtree(self.folder, ignore_errors=True)


def _fmi2_callbacks(instance: Instance) -> Any:
    from fmpy import calloc, free
    from fmpy.fmi2 import (
        fmi2CallbackAllocateMemoryTYPE,
        fmi2CallbackFreeMemoryTYPE,
        fmi2CallbackFunctions,
        fmi2CallbackLoggerTYPE,
    )

    def log2(_env: Any, _instance: Any, status: int, _category: Any, message: bytes) -> None:
        instance.log(status, message)

    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(log2)
    callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    return callbacks
