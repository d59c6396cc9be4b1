"""Export a level controller as an FMI 2.0 or 3.0 co-simulation FMU (C), next to the plant's.

The PI of :class:`gatetwin.mpc.pi.PiController` becomes a C FMU built from the plant FMU's
unchanged glue (``fmi2_glue.c`` or ``fmi3_glue.c``, ``component.h``, ``component.c``) around
its own component:
``controller_data.h`` (its ModelData) and ``controller_pi.c`` (checks, state, sampling),
which calls ``gt_pi_step``, generated from :func:`gatetwin.mpc.pi_law.pi_step` by
:mod:`gatetwin.plant.ast_render`. The interface is one :class:`ControllerDescription`,
rendered into ``model_config.h`` and ``modelDescription.xml`` by the same functions as the
plant's (:mod:`gatetwin.fmu.description`, and :mod:`gatetwin.fmu.description3` for FMI 3.0,
which adds the independent variable ``time`` one past the last value reference).

Variables (value references in this order):

* inputs ``level_<gauge>_mm`` (the plant FMU's output), ``flow_m3h``, ``setpoint_mm``;
* output ``opening_mm`` (discrete: it changes at samples only);
* tunable ``gain_mm_per_mm`` (``Kc``), ``integral_time_s`` (``Ti``), ``tracking_time_s``
  (``Tt``), ``opening_min_mm``, ``opening_max_mm``, ``opening_rate_mm_s``;
* fixed ``sample_period_s`` and ``start_opening_mm``;
* tunable ``filter_time_s`` (``Tf`` of the level's measurement filter).

Start values: SIMC on the model's FOPDT (for the settings' level filter, none by default) at
the demo's discharge and the demo's PI limits and
start opening (:class:`gatetwin.mpc.demo.DemoSettings`, :func:`gatetwin.mpc.demo.pi_controller`).
Sampling semantics: ``controller_pi.c``. Only the PI is built here; this module does not run
controllers (see :mod:`gatetwin.mpc.fmu_controller` and :mod:`gatetwin.ssp`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import os
import re
import shutil
import tempfile
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from gatetwin.errors import ExportError, OutputError
from gatetwin.fmu.c_build import (
    CFLAGS,
    FMI_APIS,
    build_description_xml,
    check_fmi_version,
    package_host_fmu,
    templates_dir,
)
from gatetwin.fmu.controller_settings import controller_plant, derived_settings
from gatetwin.fmu.description import (
    VariableSpec,
    component_config_lines,
    guid_of,
    output_name,
    variable_table_lines,
)
from gatetwin.plant.model import FopdtPlant, Plant
from gatetwin.plant.simulate import ARX_MAX_SUBSTEPS, ARX_STEP_RTOL

if TYPE_CHECKING:
    from gatetwin.modelfile import ModelFile
    from gatetwin.mpc.demo import DemoSettings

#: Controllers a model can be exported with (``mpc``: :mod:`gatetwin.fmu.mpc_controller`).
CONTROLLER_KINDS = ("pi", "mpc")
#: The FMI API a controller FMU carries by default (FMI 3.0: ``fmi_version="3.0"``).
FMI_API = FMI_APIS["2.0"]
#: The component's C files and headers, the same under either FMI API (``pi_law.*`` are
#: generated).
PI_COMPONENT_SOURCES = ("component.c", "controller_pi.c", "pi_law.c")
PI_COMPONENT_HEADERS = ("component.h", "controller_data.h", "pi_law.h")
#: The files :func:`generated_pi_law` writes.
PI_GENERATED = ("pi_law.c", "pi_law.h")
#: The C files of the FMI 2.0 PI controller FMU, in compile order, and its headers.
PI_SOURCES = (*FMI_API.glue_sources, *PI_COMPONENT_SOURCES)
PI_HEADERS = (*FMI_API.glue_headers, *PI_COMPONENT_HEADERS)
#: Prefix of the generated C functions (as blocks.c's).
PREFIX = "gt_"
#: A communication step may be this far (relative) from a whole number of samples (the ARX's
#: rule), and span at most this many samples.
STEP_RTOL = ARX_STEP_RTOL
MAX_SAMPLES_PER_STEP = ARX_MAX_SUBSTEPS
_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]{0,63}")


@dataclass(frozen=True)
class ControllerDescription:
    """The interface of a controller FMU (see the module for its variables).

    Attributes
    ----------
    model_identifier, guid : str
        FMI identity.
    kind : str
        ``"pi"``.
    gauge : str
        Gauge whose level the controller reads.
    summary : str
        The modelDescription's ``description``.
    step_size_s : float
        The sample period: the default experiment's step size, s.
    variables : tuple of VariableSpec
        Every Real variable, in value-reference order.
    provenance : dict
        What the controller was built from (``resources/provenance.json``).
    """

    model_identifier: str
    guid: str
    kind: str
    gauge: str
    summary: str
    step_size_s: float
    variables: tuple[VariableSpec, ...]
    provenance: dict[str, Any] = field(default_factory=dict)

    @property
    def output(self) -> VariableSpec:
        return next(v for v in self.variables if v.causality == "output")

    def vr(self, name: str) -> int:
        return next(v.vr for v in self.variables if v.name == name)

    def start(self, name: str) -> float:
        return float(next(v.start for v in self.variables if v.name == name) or 0.0)


def pi_files(fmi_version: str = "2.0") -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The C files (in compile order) and the headers of the PI controller FMU that carries
    ``fmi_version``'s API; raises :class:`ExportError` for a version no glue exists for."""
    api = FMI_APIS[check_fmi_version(fmi_version)]
    return (*api.glue_sources, *PI_COMPONENT_SOURCES), (*api.glue_headers, *PI_COMPONENT_HEADERS)


def _export_mpc(model: ModelFile, out_path: str | os.PathLike[str],
                settings: DemoSettings | None, model_name: str | None,
                fmi_version: str, without_effects: bool) -> Path:  # fmt: skip
    """The MPC controller FMU (:func:`gatetwin.fmu.mpc_controller.export_mpc_controller`)."""
    from dataclasses import replace

    from gatetwin.fmu.mpc_controller import export_mpc_controller

    plant = controller_plant(model)
    if without_effects:
        plant = replace(plant, effects=())
    settings = settings or derived_settings(model, plant)
    return export_mpc_controller(plant, out_path,
                                 settings=settings.mpc if settings else None,
                                 model_name=model_name or f"{model.name}_mpc",
                                 fmi_version=fmi_version)  # fmt: skip


def check_controller_kind(kind: str) -> None:
    """Raise :class:`ExportError` unless ``kind`` is a controller this package builds."""
    if kind not in CONTROLLER_KINDS:
        raise ExportError(f"controller kind must be one of {', '.join(CONTROLLER_KINDS)} "
                          f"(got {kind!r})")  # fmt: skip


def rest_level_mm(plant: Plant, opening_mm: float, flow_m3h: float) -> float:
    """The plant's steady level at the inputs (the Python reference, equal to its FMU's)."""
    from gatetwin.plant.simulate import PlantSimulator

    sim = PlantSimulator(plant)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # Q beyond the knots: clamped
        sim.initialize(opening_mm, flow_m3h)
    return float(sim.level_mm)


def describe_pi_controller(
    plant: Plant,
    model_identifier: str,
    *,
    settings: DemoSettings | None = None,
    provenance: dict[str, Any] | None = None,
    start_opening_mm: float | None = None,
) -> ControllerDescription:
    """The PI controller FMU's description for ``plant`` (an FOPDT; SIMC tuning at the
    settings' point); ``start_opening_mm`` (default the settings') is where it starts at rest.

    Raises
    ------
    ExportError
        The plant is not an FOPDT, the identifier is not a C identifier, or the tuning fails.
    """
    from gatetwin.errors import GatetwinError
    from gatetwin.mpc.demo import DemoSettings, pi_controller

    if not isinstance(plant, FopdtPlant):
        raise ExportError(f"the PI controller is tuned by SIMC from an FOPDT model; got a "
                          f"{plant.kind} model")  # fmt: skip
    if not _IDENTIFIER.fullmatch(model_identifier):
        raise ExportError(f"controller name {model_identifier!r} must be a C identifier "
                          "(letters, digits, _; <= 64 chars)")  # fmt: skip
    s = settings or DemoSettings()
    try:
        pi = pi_controller(plant, s)
    except GatetwinError as exc:
        raise ExportError(f"PI tuning: {exc}") from None
    start = s.opening_mm if start_opening_mm is None else float(start_opening_mm)
    if not math.isfinite(start):
        raise ExportError(f"start opening {start_opening_mm} mm must be finite")
    level = rest_level_mm(plant, start, s.flow_m3h)
    variables = _pi_variables(plant.gauge, pi, start, s.flow_m3h, level)
    facts = {
        "controller": "pi",
        "tuning": pi.tuning.to_dict(),
        "settings": dataclasses.asdict(pi.settings),
        "tracking_time_s": pi.tracking_time_s,
        "start_opening_mm": start,
        **(provenance or {}),
    }
    t = pi.tuning
    summary = (
        f"gatetwin PI controller of the level at gauge {plant.gauge}: SIMC tuning at Q = "
        f"{s.flow_m3h:g} m3/h (Kc {t.gain_mm_per_mm:.4g} mm/mm, Ti {t.integral_time_s:.4g} s, "
        f"level filter Tf {t.filter_time_s:.4g} s), "
        f"rate and range limits, back-calculation anti-windup; sample period "
        f"{pi.settings.sample_period_s:g} s"
    )
    return ControllerDescription(
        model_identifier=model_identifier,
        guid=guid_of(
            [
                [v.name for v in variables],
                [v.start for v in variables],
                model_identifier,
                facts,
                f"c:{_code_digest()}",
            ]
        ),  # fmt: skip
        kind="pi",
        gauge=plant.gauge,
        summary=summary,
        step_size_s=pi.settings.sample_period_s,
        variables=variables,
        provenance=facts,
    )


def _pi_variables(
    gauge: str, pi: Any, start_opening_mm: float, flow_m3h: float, level_mm: float
) -> tuple[VariableSpec, ...]:
    s, t = pi.settings, pi.tuning
    lo, hi = s.opening_range_mm
    rows: list[tuple[str, str, str, str | None, str, str, float | None]] = [
        (output_name(gauge), "input", "continuous", None, "mm",
         f"Level at gauge {gauge} (the plant FMU's output), sampled at each step's start",
         level_mm),
        ("flow_m3h", "input", "continuous", None, "m3/h",
         "Discharge Q (not used by the PI; the plants' second input)", flow_m3h),
        ("setpoint_mm", "input", "continuous", None, "mm",
         "Level set-point, sampled at each step's start", level_mm),
        ("opening_mm", "output", "discrete", "calculated", "mm",
         "Gate opening of the last sample (start_opening_mm before the first step)", None),
        ("gain_mm_per_mm", "parameter", "tunable", "exact", "mm/mm",
         "Kc: opening change per mm of level error (error = set-point - level)",
         t.gain_mm_per_mm),
        ("integral_time_s", "parameter", "tunable", "exact", "s", "Ti (> 0)",
         t.integral_time_s),
        ("tracking_time_s", "parameter", "tunable", "exact", "s",
         "Tt: back-calculation (anti-windup) time (> 0)", pi.tracking_time_s),
        ("opening_min_mm", "parameter", "tunable", "exact", "mm", "Smallest opening (>= 0)", lo),
        ("opening_max_mm", "parameter", "tunable", "exact", "mm", "Largest opening", hi),
        ("opening_rate_mm_s", "parameter", "tunable", "exact", "mm/s", "Largest gate speed (> 0)",
         s.opening_rate_mm_s),
        ("sample_period_s", "parameter", "fixed", "exact", "s",
         "Ts: communication steps must be whole multiples", s.sample_period_s),
        ("start_opening_mm", "parameter", "fixed", "exact", "mm",
         "Opening at rest: the first output and the integral's start (bumpless)",
         start_opening_mm),
        ("filter_time_s", "parameter", "tunable", "exact", "s",
         "Tf: time constant of the level's measurement filter (>= 0; 0: none), which the "
         "start values of Kc and Ti were tuned for (setting it does not retune them); the "
         "filter starts at the level input's value at initialisation", t.filter_time_s),
    ]  # fmt: skip
    return tuple(
        VariableSpec(r[0], vr, *r[1:], initial_dependency=r[0] == "start_opening_mm")
        for vr, r in enumerate(rows)
    )


def _macro(name: str) -> str:
    return "VR_LEVEL_MM" if name.startswith("level_") else "VR_" + name.upper()


def controller_config_header(desc: ControllerDescription) -> str:
    """``model_config.h`` of the controller FMU: the glue's head, the sampling limits, the
    value references and the variable table."""
    lines = [
        *component_config_lines(desc, "controller_data.h"),
        f"#define GT_STEP_RTOL {float(STEP_RTOL)!r}",
        f"#define GT_MAX_SAMPLES_PER_STEP {float(MAX_SAMPLES_PER_STEP)!r}",
        "",
        "/* value references (indices into ModelData.real) */",
        *(f"#define {_macro(v.name)} {v.vr}" for v in desc.variables if v.causality != "output"),
        f"#define VR_OUTPUT {desc.output.vr}",
    ]
    return "\n".join(lines + variable_table_lines(desc.variables))


def generated_pi_law() -> dict[str, str]:
    """File name -> text of the C rendering of :mod:`gatetwin.mpc.pi_law`."""
    from gatetwin.mpc import pi_law
    from gatetwin.plant.ast_render import c_module

    source, header = c_module(pi_law, pi_law.RENDERED_C, PREFIX)
    return {"pi_law.c": source, "pi_law.h": header}


def _code_digest() -> str:
    """sha256 (first 16 hex digits) of the code the controller FMU is built from (either FMI
    API: one GUID for both, as the plant FMUs')."""
    templates = templates_dir()
    law = Path(__file__).resolve().parents[1] / "mpc" / "pi_law.py"
    names = {n for version in FMI_APIS for files in pi_files(version) for n in files}
    digest = hashlib.sha256()
    for path in [*(templates / n for n in sorted(names - set(PI_GENERATED))), law]:
        digest.update(path.name.encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()[:16]


def write_controller_sources(
    desc: ControllerDescription, sources_dir: Path, fmi_version: str = "2.0"
) -> tuple[str, ...]:
    """The templates, the generated ``pi_law.c``/``.h`` and ``model_config.h`` in
    ``sources_dir``, with ``BUILD.txt`` and ``buildDescription.xml``; returns the C files in
    compile order."""
    c_files, headers = pi_files(fmi_version)
    templates = templates_dir()
    sources_dir.mkdir(parents=True, exist_ok=True)
    generated = generated_pi_law()
    for name in (*c_files, *headers, FMI_APIS[fmi_version].license):
        if name not in generated:
            shutil.copyfile(templates / name, sources_dir / name)
    for name, text in generated.items():
        (sources_dir / name).write_text(text, encoding="utf-8")
    (sources_dir / "model_config.h").write_text(controller_config_header(desc), encoding="utf-8")
    line = " ".join(["cc", *CFLAGS, "-o", f"{desc.model_identifier}.so", *c_files, "-lm"])
    (sources_dir / "BUILD.txt").write_text(
        "Build the FMU binary from this folder (any C99 compiler with the same flags):\n\n"
        f"    {line}\n\nmodel_config.h is generated by gatetwin (gatetwin.fmu.controller), "
        "pi_law.c and pi_law.h\nfrom gatetwin.mpc.pi_law; the other files are gatetwin's fixed "
        "FMU templates.\n",
        encoding="utf-8",
    )
    (sources_dir / "buildDescription.xml").write_bytes(build_description_xml(desc, c_files))
    return c_files


def build_controller_fmu(
    desc: ControllerDescription, work: Path, out: Path, fmi_version: str = "2.0"
) -> None:
    """Lay out the controller FMU in ``work/fmu`` (sources, the host's binary, resources,
    modelDescription.xml) in ``fmi_version``'s layout and zip it into ``out``."""
    fmu_dir = work / "fmu"
    c_files = write_controller_sources(desc, fmu_dir / "sources", fmi_version)
    package_host_fmu(desc, fmu_dir, c_files, out, desc.provenance, fmi_version)


def export_controller(
    model: ModelFile,
    kind: str,
    out_path: str | os.PathLike[str],
    *,
    settings: DemoSettings | None = None,
    model_name: str | None = None,
    fmi_version: str = "2.0",
    without_effects: bool = False,
) -> Path:
    """Build the ``kind`` controller FMU of ``model`` at ``out_path``; return its path.

    Parameters
    ----------
    model : ModelFile
        A read model file (:func:`gatetwin.modelfile.read_model_file`) of an FOPDT or a
        physical plant (linearised along its discharge range,
        :func:`gatetwin.fmu.controller_settings.controller_plant`).
    kind : {"pi", "mpc"}
        ``"pi"``: the SIMC PI; ``"mpc"``: the demo's single-point MPC
        (:func:`gatetwin.fmu.mpc_controller.export_mpc_controller`, with ``settings.mpc``).
    out_path : path
        Target ``.fmu``, written atomically (built next to it, moved into place on success).
    settings : DemoSettings, optional
        Operating point, start opening, limits, horizon and weights (default: derived from
        the model, :func:`gatetwin.fmu.controller_settings.derived_settings`).
    model_name : str, optional
        modelIdentifier (default ``<model name>_pi``).
    fmi_version : {"2.0", "3.0"}
        FMI co-simulation API of the FMU: same variables, value references and outputs
        (FMI 3.0 adds ``time``).
    without_effects : bool
        ``mpc``: control the model's FOPDT with its effect blocks dropped (the MPC controller
        FMU does not cover them; a model with effect blocks is refused otherwise).

    Raises
    ------
    ExportError
        Unknown kind or FMI version, a model that is neither an FOPDT nor a physical model,
        no C compiler, build failure.
    OutputError
        The FMU cannot be written where asked.
    """
    check_controller_kind(kind)
    pi_files(fmi_version)
    if kind == "mpc":
        return _export_mpc(model, out_path, settings, model_name, fmi_version, without_effects)
    target = Path(out_path)
    if target.suffix.lower() != ".fmu":
        raise ExportError(f"output {target} must end in .fmu")
    provenance = {"model": model.name, "model_sha256": model.sha256}
    plant = controller_plant(model)
    if settings is None:
        settings = derived_settings(model, plant)
        provenance["settings_from"] = "the model file (gatetwin.fmu.controller_settings)"
    desc = describe_pi_controller(plant, model_name or f"{model.name}_{kind}",
                                  settings=settings, provenance=provenance)  # fmt: skip
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(prefix=f".{target.name}.", dir=target.parent) as tmp:
            built = Path(tmp) / target.name
            build_controller_fmu(desc, Path(tmp), built, fmi_version)
            os.replace(built, target)
    except OSError as exc:
        raise OutputError(f"{target}: cannot write the FMU ({exc.strerror or exc})") from None
    return target


__all__ = [
    "CONTROLLER_KINDS",
    "ControllerDescription",
    "build_controller_fmu",
    "check_controller_kind",
    "controller_config_header",
    "describe_pi_controller",
    "export_controller",
    "generated_pi_law",
    "pi_files",
    "rest_level_mm",
    "write_controller_sources",
]
