"""One table per record: the local FOPDT against the envelope FOPDT and the physical model.

Each plant runs freely on the record (reconstructed opening, measured inflow) through the
reference simulator, which the C and python FMUs equal to 1e-9 mm; fit %, RMSE and bias are
the harness's own metrics, next to the record's noise-floor fit. The local FOPDT is the
envelope FOPDT without its ``envelope`` (its schedule on the operating line, as the models
were before the envelope).

Not for: FMU checks (the validation matrix does those).
"""

from __future__ import annotations

import warnings
from dataclasses import replace
from typing import Any

from gatetwin.identification.preprocess import reconstructed_opening
from gatetwin.noise import record_noise_floor
from gatetwin.plant.model import FopdtPlant, Plant
from gatetwin.plant.simulate import simulate
from gatetwin.records import Record
from gatetwin.validation.compare import free_run_metrics, noise_floor_fit_percent

__all__ = ["families_markdown", "family_row", "local_form"]


def local_form(plant: FopdtPlant) -> FopdtPlant:
    """The FOPDT around its operating line: the envelope removed."""
    return replace(plant, envelope=None)


def family_row(record: Record, plants: dict[str, Plant], gauge: str) -> dict[str, Any]:
    """Free-run fit %, RMSE and bias (mm) of each named plant on ``record``, and its floor."""
    e = reconstructed_opening(record.time_s, record.opening_mm, record.hold)
    y = record.levels_mm[gauge]
    row: dict[str, Any] = {"record": record.path.rsplit("/", 1)[-1].removesuffix(".csv")
                           if record.path else "", "gauge": gauge}  # fmt: skip
    floor = record_noise_floor(record, gauge)
    row["noise_floor_fit_percent"] = noise_floor_fit_percent(floor.sigma_mm, y)[0]
    for name, plant in plants.items():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # outside the Q range: stated
            y_sim = simulate(plant, record.time_s, e, record.flow_m3h)
        m = free_run_metrics(y, y_sim)
        row[name] = {"fit_percent": m.fit_percent, "rmse_mm": m.rmse_mm, "bias_mm": m.bias_mm}
    return row


def families_markdown(rows: list[dict[str, Any]], names: list[str]) -> str:
    """The rows as a Markdown table: one line per record, fit / RMSE / bias per plant."""
    head = "| record | floor fit % | " + " | ".join(f"{n}: fit % / RMSE / bias (mm)"
                                                   for n in names) + " |"  # fmt: skip
    lines = [head, "|" + "---|" * (2 + len(names))]
    for r in rows:
        cells = [f"{r[n]['fit_percent']:.1f} / {r[n]['rmse_mm']:.1f} / {r[n]['bias_mm']:+.1f}"
                 for n in names]  # fmt: skip
        lines.append(f"| {r['record']} | {r['noise_floor_fit_percent']:.1f} | "
                     + " | ".join(cells) + " |")  # fmt: skip
    return "\n".join(lines) + "\n"
