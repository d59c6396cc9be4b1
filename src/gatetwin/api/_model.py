"""Model: an identified plant together with its model file, and what one does with it.

A :class:`Model` wraps one :class:`~gatetwin.modelfile.ModelFile` (the JSON document
``gatetwin identify`` and ``gatetwin run`` write, and its plant) and offers the verbs a
notebook needs: save, simulate, linearise, hand to python-control, export as an FMU. Each
verb calls the library function that does the work (:mod:`gatetwin.modelfile`,
:mod:`gatetwin.plant`, :mod:`gatetwin.fmu`); none of the arithmetic lives here.
"""

from __future__ import annotations

import copy
import hashlib
import json
import os
from collections.abc import Iterator, Mapping
from dataclasses import asdict, dataclass
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from gatetwin.api._simulation import SimulationResult, simulate_plant

if TYPE_CHECKING:  # model files and plants pull in scipy: imported where they are used
    from gatetwin.modelfile import ModelFile
    from gatetwin.plant.model import ArxPlant, FopdtPlant, Plant

__all__ = ["Model", "ModelSet", "OperatingPoint", "load_model", "model_from_document"]

#: FMI versions :meth:`Model.export_fmu` writes.


@dataclass(frozen=True)
class OperatingPoint:
    """A model's local FOPDT at one discharge and opening.

    Attributes
    ----------
    flow_m3h : float
        Discharge, m³/h.
    opening_mm : float
        Gate opening, mm.
    gain_mm_per_mm : float
        K: steady level change per mm of opening, mm/mm.
    time_constant_s : float
        T, s (NaN for an ARX model without a real dominant pole).
    dead_time_s : float
        L, s.
    level_mm : float
        Steady level at the gauge for these inputs, mm.
    source : str
        Where K, T, L come from: ``"envelope"`` (gate law and storage of an envelope
        FOPDT), ``"physical"`` (the physical kernel), ``"schedule"`` (a local FOPDT's
        schedule on Q) or ``"arx"`` (DC gain and dominant pole of the ARX coefficients at Q;
        L is the ``nk - 1`` whole samples beyond the hold).

    Examples
    --------
    >>> from gatetwin import bundled_records_dir, identify
    >>> point = identify(bundled_records_dir() / "C.csv").at(29.5, 35.0)  # ARX(2,2,1)
    >>> point.source, point.dead_time_s, bool(point.gain_mm_per_mm < 0)
    ('arx', 0.0, True)
    """

    flow_m3h: float
    opening_mm: float
    gain_mm_per_mm: float
    time_constant_s: float
    dead_time_s: float
    level_mm: float
    source: str

    def to_dict(self) -> dict[str, Any]:
        """The fields as a JSON-ready dict."""
        return asdict(self)


def _document_bytes(content: dict[str, Any]) -> bytes:
    """The bytes :func:`gatetwin.modelfile.write_model_file` writes for ``content``."""
    return (json.dumps(content, indent=2, allow_nan=False) + "\n").encode("utf-8")


def model_from_document(content: dict[str, Any], path: str = "") -> Model:
    """A :class:`Model` of a model-file document built in memory (not yet saved).

    The document is normalised through JSON, so the model equals the one read back after
    :meth:`Model.save`, hash included.
    """
    from gatetwin.modelfile import ModelFile
    from gatetwin.plant.model import plant_from_dict

    raw = _document_bytes(content)
    doc = json.loads(raw)
    plant = plant_from_dict(doc["plant"])
    return Model(ModelFile(str(doc["name"]), plant, doc, hashlib.sha256(raw).hexdigest(), path))


def _arx_point(plant: ArxPlant, flow_m3h: float, opening_mm: float) -> OperatingPoint:
    from gatetwin.identification.metrics import dc_gain, dominant_pole

    a, b = plant.coefficients(flow_m3h)
    gain = dc_gain(a, b)
    tau = dominant_pole(a, plant.sample_period_s).time_constant_s
    level = plant.schedule.at("level_ref_mm", flow_m3h) + gain * (opening_mm - plant.opening_ref_mm)
    return OperatingPoint(flow_m3h, opening_mm, gain, np.nan if tau is None else tau,
                          (plant.nk - 1) * plant.sample_period_s, level, "arx")  # fmt: skip


def _local_point(plant: FopdtPlant, flow_m3h: float, opening_mm: float) -> OperatingPoint:
    k, tau, delay, level_ref = (plant.schedule.at(c, flow_m3h) for c in plant.columns)
    level = level_ref + k * (opening_mm - plant.opening_ref_mm)
    return OperatingPoint(flow_m3h, opening_mm, k, tau, delay, level, "schedule")


@dataclass(frozen=True, eq=False)
class Model:
    """An identified model of the level at one gauge: its plant and its model file.

    Get one from :func:`gatetwin.identification`, :func:`gatetwin.identify_folder` or
    :func:`gatetwin.load_model`.

    Attributes
    ----------
    file : ModelFile
        The model file: ``name``, ``plant``, ``content`` (the whole JSON document),
        ``sha256`` (of the file's bytes, or of the bytes :meth:`save` writes) and ``path``
        (where it was read from; "" for a model not read from a file).

    Examples
    --------
    >>> from gatetwin import bundled_records_dir, identify
    >>> model = identify(bundled_records_dir() / "A.csv", gauge="3F")
    >>> model
    Model('fopdt_3F': fopdt of gauge 3F, Q 29.4–29.7 m³/h)
    >>> round(model.at(29.5, 15.0).gain_mm_per_mm)  # mm of level per mm of opening
    -15
    """

    file: ModelFile

    @property
    def name(self) -> str:
        """The model's name (also its FMU's modelIdentifier)."""
        return self.file.name

    @property
    def plant(self) -> Plant:
        """The plant object the simulators, FMUs and MPC render."""
        return self.file.plant

    @property
    def gauge(self) -> str:
        """The gauge whose level the model gives (output ``level_<gauge>_mm``)."""
        return self.plant.gauge

    @property
    def family(self) -> str:
        """``"fopdt"``, ``"arx"`` or ``"physical"``."""
        return self.plant.kind

    @property
    def path(self) -> str:
        """Where the model file was read from ("" when it was built in memory)."""
        return self.file.path

    @property
    def sha256(self) -> str:
        """Hash of the model file's bytes (what an FMU's provenance quotes)."""
        return self.file.sha256

    @property
    def validity(self) -> dict[str, list[float]]:
        """The ranges the model states it is valid over: ``flow_m3h``, ``opening_mm``,
        ``level_mm`` as ``[low, high]``, each only when stated
        (:func:`gatetwin.modelfile.validity_envelope`)."""
        return self.file.validity_envelope

    def __repr__(self) -> str:
        lo, hi = self.file.validity_flow_m3h
        kind = "envelope fopdt" if getattr(self.plant, "envelope", None) else self.family
        return f"Model({self.name!r}: {kind} of gauge {self.gauge}, Q {lo:g}–{hi:g} m³/h)"

    def to_dict(self) -> dict[str, Any]:
        """A copy of the model file's JSON document.

        Examples
        --------
        >>> from gatetwin import bundled_records_dir, identify
        >>> identify(bundled_records_dir() / "A.csv").to_dict()["plant"]["kind"]
        'fopdt'
        """
        return copy.deepcopy(self.file.content)

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the model file (the JSON ``gatetwin identify`` and ``gatetwin run`` write).

        Parameters
        ----------
        path : str or PathLike
            Target ``.json`` file, written atomically.

        Returns
        -------
        Path
            ``path``.

        Examples
        --------
        >>> from gatetwin import bundled_records_dir, identify, load_model
        >>> model = identify(bundled_records_dir() / "A.csv")
        >>> load_model(model.save("fopdt_3F.json")).sha256 == model.sha256
        True
        """
        from gatetwin.modelfile import write_model_file

        return write_model_file(os.fspath(path), self.file.content)

    def simulate(self, opening_mm: Any, flow_m3h: Any, time_s: Any = None, *,
                 sample_period_s: float | None = None,
                 level0: float | None = None) -> SimulationResult:  # fmt: skip
        """Run the model free on given inputs (the Python reference simulation).

        Parameters
        ----------
        opening_mm : float or array_like
            Gate opening, mm; each value held until the next sample.
        flow_m3h : float or array_like
            Discharge, m³/h; each value held until the next sample.
        time_s : array_like, optional
            Sample times, s, strictly increasing. Give this or ``sample_period_s``.
        sample_period_s : float, optional
            Uniform sample period, s (an ARX model defaults to its own).
        level0 : float, optional
            Shift the simulated level by a constant so that it starts at ``level0`` mm
            (a gauge-datum correction; the model still starts at its equilibrium for the
            first inputs).

        Returns
        -------
        SimulationResult

        Raises
        ------
        SimulationError
            Inputs of the wrong length, not finite or physically impossible, times not
            increasing.

        Examples
        --------
        >>> from gatetwin import bundled_records_dir, identify
        >>> model = identify(bundled_records_dir() / "A.csv")
        >>> result = model.simulate(15.0, 29.5, time_s=[0.0, 60.0, 120.0])
        >>> result.level_mm.round(1).tolist()  # constant inputs: the steady level
        [231.2, 231.2, 231.2]
        """
        return simulate_plant(self.plant, self.name, opening_mm, flow_m3h, time_s,
                              sample_period_s, level0)  # fmt: skip

    def at(self, flow_m3h: float, opening_mm: float) -> OperatingPoint:
        """The local K, T, L and steady level at discharge ``flow_m3h`` and ``opening_mm``.

        An envelope FOPDT and a physical model linearise their gate law and storage there
        (:func:`gatetwin.plant.model.local_fopdt`); a local FOPDT reads its schedule on Q
        (the level on its operating line extended with slope K); an ARX model gives its DC
        gain and dominant-pole time constant at Q. Effect blocks are not included. Outside
        the schedule's discharge range a schedule's parameters are those of the nearest
        knot (as the simulation clamps them); check :attr:`validity` first.

        Parameters
        ----------
        flow_m3h : float
            Discharge, m³/h.
        opening_mm : float
            Gate opening, mm.

        Returns
        -------
        OperatingPoint

        Examples
        --------
        >>> from gatetwin import bundled_records_dir, identify
        >>> point = identify(bundled_records_dir() / "A.csv").at(29.5, 15.0)
        >>> point.source, round(point.time_constant_s)
        ('schedule', 75)
        """
        from gatetwin.plant.inputs import check_inputs
        from gatetwin.plant.model import ArxPlant, FopdtPlant, PhysicalPlant, local_fopdt

        check_inputs(flow_m3h=float(flow_m3h), opening_mm=float(opening_mm))
        q, e = float(flow_m3h), float(opening_mm)
        plant = self.plant
        if isinstance(plant, ArxPlant) and plant.envelope is None:
            return _arx_point(plant, q, e)
        if isinstance(plant, FopdtPlant) and plant.envelope is None:
            return _local_point(plant, q, e)
        local = local_fopdt(plant, q, e)
        level = local["level_mm"]
        if isinstance(plant, PhysicalPlant):
            level += plant.schedule.at("level_ref_mm", q)
        return OperatingPoint(
            q,
            e,
            local["gain_mm_per_mm"],
            local["time_constant_s"],
            local["dead_time_s"],
            level,
            "physical" if isinstance(plant, PhysicalPlant) else "envelope",
        )

    def operating_point(self) -> tuple[float, float]:
        """The default (discharge m³/h, opening mm) of :meth:`to_control`.

        The middle of the schedule's discharge range, and there the operating opening the
        model was identified around (interpolated between its knots), else the middle of
        its stated opening range, else its reference opening.

        Examples
        --------
        >>> from gatetwin import bundled_records_dir, identify
        >>> [round(v, 2) for v in identify(bundled_records_dir() / "A.csv").operating_point()]
        [29.55, 15.0]
        """
        lo, hi = self.plant.schedule.flow_range_m3h
        q = 0.5 * (lo + hi)
        validity = self.file.content.get("validity", {})
        openings = validity.get("opening_mm_at_knots")
        if openings and len(openings) == len(self.plant.schedule.flow_m3h):
            return q, float(np.interp(q, self.plant.schedule.flow_m3h, openings))
        if "opening_mm" in self.validity:
            return q, float(np.mean(self.validity["opening_mm"]))
        return q, float(self.plant.opening_ref_mm)

    def to_control(self, flow_m3h: float | None = None, opening_mm: float | None = None, *,
                   pade_order: int = 3, dt: float | None = None) -> Any:  # fmt: skip
        """The model's small-signal dynamics as a python-control ``TransferFunction``.

        Input: opening deviation (mm); output: level deviation (mm). An FOPDT, envelope
        FOPDT or physical model gives ``K e^{-Ls} / (T s + 1)`` at (Q, e) (see :meth:`at`);
        an ARX model its own discrete transfer function at Q.

        Parameters
        ----------
        flow_m3h, opening_mm : float, optional
            The operating point; default :meth:`operating_point`.
        pade_order : int
            Order of the Padé approximant of the dead time (continuous form only).
        dt : float, optional
            Sample period, s: a discrete transfer function, the zero-order-hold equivalent
            with the dead time exact (whole samples and a fraction). An ARX model accepts
            only its own sample period.

        Returns
        -------
        control.TransferFunction

        Examples
        --------
        >>> from gatetwin import bundled_records_dir, identify
        >>> model = identify(bundled_records_dir() / "A.csv")
        >>> g = model.to_control(dt=1.2)
        >>> bool(abs(g.dcgain() - model.at(*model.operating_point()).gain_mm_per_mm) < 1e-9)
        True
        """
        from gatetwin.api._control import transfer_function

        default_q, default_e = self.operating_point()
        q = default_q if flow_m3h is None else float(flow_m3h)
        e = default_e if opening_mm is None else float(opening_mm)
        return transfer_function(self, q, e, pade_order, dt)

    def export_fmu(self, path: str | os.PathLike[str], backend: str = "c",
                   fmi_version: str = "2.0") -> Path:  # fmt: skip
        """Export the model as a co-simulation FMU (the same FMU as ``gatetwin export``).

        Parameters
        ----------
        path : str or PathLike
            Target ``.fmu`` file, written atomically.
        backend : {"c", "python"}
            Native C compiled with the system compiler, or a pythonfmu FMU.
        fmi_version : {"2.0", "3.0"}
            FMI version (3.0: C backend only); same variables, value references and outputs.

        Returns
        -------
        Path
            ``path``.

        Raises
        ------
        ExportError
            Unknown backend or FMI version, no C compiler, build failure.

        Examples
        --------
        >>> from gatetwin import bundled_records_dir, identify
        >>> model = identify(bundled_records_dir() / "A.csv")
        >>> model.export_fmu("fopdt_3F.fmu").name
        'fopdt_3F.fmu'
        """
        from gatetwin.fmu import export_fmu
        from gatetwin.fmu.provenance import fmu_provenance

        return export_fmu(self.plant, os.fspath(path), backend=backend, model_name=self.name,
                          provenance=fmu_provenance(self.file),
                          fmi_version=fmi_version)  # fmt: skip


def load_model(path: str | os.PathLike[str]) -> Model:
    """Read a model file (as written by ``gatetwin identify``, ``models``, ``run``).

    Parameters
    ----------
    path : str or PathLike
        The model file.

    Returns
    -------
    Model

    Raises
    ------
    ModelFileError
        The file cannot be read or does not follow the model-file schema.

    Examples
    --------
    >>> from gatetwin import bundled_records_dir, identify, load_model
    >>> path = identify(bundled_records_dir() / "A.csv").save("model.json")
    >>> load_model(path).name
    'fopdt_3F'
    """
    from gatetwin.modelfile import read_model_file

    return Model(read_model_file(os.fspath(path)))


class ModelSet(Mapping[str, Model]):
    """The models identified from one records folder, by name (a read-only mapping).

    Attributes
    ----------
    folder : Path or None
        The records folder they were identified from.

    Examples
    --------
    >>> from gatetwin import ModelSet, bundled_records_dir, identify
    >>> models = ModelSet({"fopdt_3F": identify(bundled_records_dir() / "A.csv")})
    >>> list(models), models["fopdt_3F"].gauge
    (['fopdt_3F'], '3F')
    """

    def __init__(self, models: Mapping[str, Model], folder: Path | None = None) -> None:
        self._models = dict(sorted(models.items()))
        self.folder = folder

    def __getitem__(self, name: str) -> Model:
        try:
            return self._models[name]
        except KeyError:
            raise KeyError(f"no model {name!r}; the set holds "
                           f"{', '.join(self._models) or 'none'}") from None  # fmt: skip

    def __iter__(self) -> Iterator[str]:
        return iter(self._models)

    def __len__(self) -> int:
        return len(self._models)

    def __repr__(self) -> str:
        return f"ModelSet({', '.join(self._models)})"

    def save(self, folder: str | os.PathLike[str]) -> list[Path]:
        """Write every model file and the schema into ``folder`` (as ``gatetwin models``).

        Returns
        -------
        list of Path
            ``schema.json`` then one ``<name>.json`` per model.

        Examples
        --------
        >>> from gatetwin import ModelSet, bundled_records_dir, identify
        >>> models = ModelSet({"fopdt_3F": identify(bundled_records_dir() / "A.csv")})
        >>> [p.name for p in models.save("models")]
        ['schema.json', 'fopdt_3F.json']
        """
        from gatetwin._io import write_text_atomic

        out = Path(os.fspath(folder))
        schema = (resources.files("gatetwin") / "data" / "model_schema.json").read_text("utf-8")
        paths = [write_text_atomic(out / "schema.json", schema)]
        return paths + [m.save(out / f"{name}.json") for name, m in self._models.items()]
