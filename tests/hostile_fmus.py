"""FMUs that misbehave on purpose: a right C FMU rebuilt from its own sources with its
``fmi2DoStep`` ending the process, hanging, writing through a null pointer or returning NaN
once it has made :data:`AFTER_STEPS` steps with a discharge above a threshold (the harness's
and the SSP master's isolation tests run them)."""

from __future__ import annotations

import re
import subprocess
import zipfile
from pathlib import Path

from fmpy import platform, read_model_description, sharedLibraryExtension

from fmu_support import compiler

#: Steps the hostile FMUs make normally before they misbehave (B's sample 11 on).
AFTER_STEPS = 10
#: Discharge above which they misbehave, m³/h: between A's 29.5 and B's 72.5.
FLOW_ABOVE_M3H = 50.0
ACTIONS = {
    "exit": "exit(0);",
    "abort": "abort();",
    "null_write": "{ volatile int *volatile p = 0; *p = 1; }",
    "hang": "{ volatile int spin = 1; while (spin) { } }",
    "nan": "",
}
WRAPPERS = """
/* ---- patched in by tests/hostile_fmus.py: a hostile FMU ---- */
#include <math.h>
#include <stdlib.h>

static int hostile_steps;

static int hostile_now(fmi2Component c)
{
    const fmi2ValueReference vr = %(flow_vr)d;
    fmi2Real flow = 0.0;
    return hostile_steps > %(after)d && hostile_get_real(c, &vr, 1, &flow) == fmi2OK &&
           flow > %(flow_above)r;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean keep)
{
    fmi2Status status = hostile_do_step(c, t, h, keep);
    hostile_steps += 1;
    if (hostile_now(c)) {
        %(action)s
    }
    return status;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       fmi2Real value[])
{
    fmi2Status status = hostile_get_real(c, vr, nvr, value);
    size_t i;
    for (i = 0; %(nan)d && i < nvr && hostile_now(c); i++) {
        value[i] = NAN;
    }
    return status;
}
"""


def patched_glue(glue: str, action: str, flow_vr: int, flow_above: float) -> str:
    renames = {"fmi2DoStep": "hostile_do_step", "fmi2GetReal": "hostile_get_real"}
    for name, new in renames.items():
        glue, n = re.subn(rf"^fmi2Status\s+{name}\s*\(", f"static fmi2Status {new}(", glue,
                          flags=re.MULTILINE)  # fmt: skip
        assert n == 1, f"fmi2_glue.c: no single definition of {name} to wrap"
    return glue + WRAPPERS % {"flow_vr": flow_vr, "after": AFTER_STEPS,
                              "flow_above": flow_above, "action": action,
                              "nan": int(not action)}  # fmt: skip


def build_hostile(good: Path, kind: str, folder: Path, flow_above: float = FLOW_ABOVE_M3H
                  ) -> Path:  # fmt: skip
    """``good`` rebuilt from its own sources with the ``kind`` misbehaviour, once it has made
    ``AFTER_STEPS`` steps with a discharge input above ``flow_above``."""
    md = read_model_description(str(good))
    identifier = md.coSimulation.modelIdentifier
    flow_vr = next(v.valueReference for v in md.modelVariables if v.name == "flow_m3h")
    work = folder / f"{kind}_build"
    with zipfile.ZipFile(good) as zf:
        zf.extractall(work)
    sources = work / "sources"
    glue = sources / "fmi2_glue.c"
    glue.write_text(patched_glue(glue.read_text(), ACTIONS[kind], flow_vr, flow_above))
    command = (sources / "BUILD.txt").read_text().splitlines()[2].split()
    command[0] = compiler()
    subprocess.run(command, cwd=sources, check=True, capture_output=True, text=True)
    binary = f"binaries/{platform}/{identifier}{sharedLibraryExtension}"
    out = folder / f"hostile_{kind}.fmu"
    with zipfile.ZipFile(good) as zin, zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as zout:
        for name in zin.namelist():
            data = (sources / Path(binary).name).read_bytes() if name == binary else zin.read(name)
            zout.writestr(name, data)
    return out
