"""``model_config.h`` of the observer FMUs (:mod:`gatetwin.fmu.observer_fmu`): the
observer's sizes, the value references its generated functions read and write, the envelope
observer's kernel parameters and the gauge-drift rule's. Built from the FMU's description and
the generated code's layout; this module builds no FMU.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from gatetwin.fmu.description import FmuDescription, output_name
from gatetwin.fmu.generated_component import c_double, config_header
from gatetwin.mpc.codegen import Layout
from gatetwin.mpc.gauge_drift import WINDOW_SAMPLES
from gatetwin.mpc.observer_codegen import (
    DRIFT_RULE,
    ENVELOPE_PREFIX,
    ESTIMATE,
    LIMITS,
    N_POINTS,
    PREFIX,
    SLOW_RULE,
)
from gatetwin.mpc.online import MAX_HORIZON_S, MONITOR

if TYPE_CHECKING:
    from gatetwin.plant.model import FopdtPlant, PhysicalPlant

#: Most samples one communication step may span (3 h 20 min of 1.2 s samples, 28 h of 10 s
#: ones): a budget of work per call (~14 µs a sample, so ~0.15 s) that keeps a huge step from
#: stalling the host.
MAX_SAMPLES_PER_STEP = 10_000


def _drift_config(desc: FmuDescription, references: tuple[str, ...],
                  prefix: str) -> tuple[list[str], dict[str, str]]:  # fmt: skip
    """The gauge-drift rule's lines of ``model_config.h`` and its ``VR_*`` names
    (``GT_DRIFT_N_REFS`` 0 without reference gauges)."""
    if not references:
        return ["/* no reference gauges: no gauge-drift rule */", "#define GT_DRIFT_N_REFS 0"], {}
    vr = {v.name: v.vr for v in desc.variables}
    lines = [
        "/* the gauge-drift rule (gatetwin.mpc.gauge_drift) */",
        f"#define GT_DRIFT_N_REFS {len(references)}",
        f"#define GT_DRIFT_WINDOW {WINDOW_SAMPLES}",
        f"#define GT_DRIFT_N_RULE {len(DRIFT_RULE)}",
        f"#define GT_DRIFT_FUNCTION {prefix}drift",
        "#define GT_DRIFT_REF_VRS {" + ", ".join(str(vr[output_name(g)]) for g in references) + "}",
        "#define GT_DRIFT_RULE_VRS {" + ", ".join(str(vr[n]) for n in DRIFT_RULE) + "}",
    ]
    named = ("gauge_slope_mm_per_s", "gauge_drift", "gauge_drift_threshold_mm_per_s")
    return lines, {n.upper(): n for n in named}


def observer_config_header(
    desc: FmuDescription,
    layout: Layout,
    sizes: dict[str, dict[str, int]],
    references: tuple[str, ...] = (),
) -> str:
    """``model_config.h`` of the observer FMU."""
    vr = {v.name: v.vr for v in desc.variables}
    limits = tuple(f"anomaly_{n}" for n in LIMITS)
    own = [
        "/* the observer */",
        f"#define GT_OBS_N_ESTIMATE {len(ESTIMATE)}",
        f"#define GT_OBS_N_MONITOR {len(MONITOR)}",
        f"#define GT_OBS_N_LIMITS {len(LIMITS)}",
        f"#define GT_OBS_MAX_HORIZON_S {c_double(MAX_HORIZON_S)}",
        f"#define GT_OBS_MAX_SAMPLES_PER_STEP {MAX_SAMPLES_PER_STEP}",
        "/* value references of the generated correct's estimate and limits, in order */",
        "#define GT_OBS_ESTIMATE_VRS {" + ", ".join(str(vr[n]) for n in ESTIMATE) + "}",
        "#define GT_OBS_LIMIT_VRS {" + ", ".join(str(vr[n]) for n in limits) + "}",
    ]
    drift, drift_vrs = _drift_config(desc, references, PREFIX)
    named = ("opening_mm", "flow_m3h", *ESTIMATE, "predicted_level_mm", "horizon_s", *limits)
    refs = {"LEVEL": output_name(desc.gauge), **{n.upper(): n for n in named}, **drift_vrs}
    return config_header(desc, "observer_data.h", layout, sizes, desc.step_size_s,
                         own + drift, refs)  # fmt: skip


def envelope_config_header(
    desc: FmuDescription,
    layout: Layout,
    sizes: dict[str, dict[str, int]],
    plant: FopdtPlant | PhysicalPlant,
    references: tuple[str, ...] = (),
) -> str:
    """``model_config.h`` of the envelope observer FMU (no schedule parameters: the plant's
    kernel parameters are a constant array)."""
    from gatetwin.mpc.envelope import envelope_parameters

    vr = {v.name: v.vr for v in desc.variables}
    limits = tuple(f"anomaly_{n}" for n in LIMITS)
    kernel = ", ".join(c_double(v) for v in envelope_parameters(plant))
    own = [
        "/* the envelope observer */",
        f"#define GT_OBS_N_ESTIMATE {len(ESTIMATE)}",
        f"#define GT_OBS_N_MONITOR {len(MONITOR)}",
        f"#define GT_OBS_N_LIMITS {len(LIMITS)}",
        f"#define GT_OBS_MAX_HORIZON_S {c_double(MAX_HORIZON_S)}",
        f"#define GT_OBS_MAX_SAMPLES_PER_STEP {MAX_SAMPLES_PER_STEP}",
        f"#define GT_ENV_N_POINTS {N_POINTS}",
        f"#define GT_ENV_N_X {2 * N_POINTS}",
        f"#define GT_ENV_N_RULE {len(SLOW_RULE)}",
        f"#define GT_ENV_KIND_INDEX {ESTIMATE.index('anomaly_kind')}",
        "/* the plant kernel's parameters (gatetwin.plant.physical_kernel.PARAMETERS) */",
        "#define GT_ENV_KERNEL_P {" + kernel + "}",
        "/* value references of the generated functions' outputs and inputs, in order */",
        "#define GT_OBS_ESTIMATE_VRS {" + ", ".join(str(vr[n]) for n in ESTIMATE) + "}",
        "#define GT_OBS_LIMIT_VRS {" + ", ".join(str(vr[n]) for n in limits) + "}",
        "#define GT_ENV_RULE_VRS {" + ", ".join(str(vr[n]) for n in SLOW_RULE) + "}",
        f"/* generated function names carry the prefix {ENVELOPE_PREFIX} */",
    ]
    named = ("opening_mm", "flow_m3h", *ESTIMATE, "predicted_level_mm", "horizon_s", *limits,
             "slow_cusum")  # fmt: skip
    drift, drift_vrs = _drift_config(desc, references, ENVELOPE_PREFIX)
    refs = {"LEVEL": output_name(desc.gauge), **{n.upper(): n for n in named}, **drift_vrs}
    return config_header(desc, "observer_envelope_data.h", layout, sizes, desc.step_size_s,
                         own + drift, refs, schedule=False)  # fmt: skip


__all__ = ["MAX_SAMPLES_PER_STEP", "envelope_config_header", "observer_config_header"]
