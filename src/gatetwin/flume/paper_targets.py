"""The reference study's published numbers (docs/reference_study.md, Tables 1–5) as data.

The flume is calibrated to these and tests hold it to them; nothing else reads them.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = [
    "GAUGES",
    "STEP_TABLES",
    "TABLE_2",
    "TABLE_3",
    "TABLE_4",
    "TABLE_5",
    "ArxRow",
    "StaticGainRow",
    "StepTable",
]

GAUGES = ("1D", "2E", "3F", "4G", "5H")


@dataclass(frozen=True)
class StepTable:
    """One step test's published table (Tables 2 and 3)."""

    condition: str
    flow_m3h: float
    opening_before_mm: float
    opening_after_mm: float
    pre_mean_mm: dict[str, float]
    pre_sd_mm: dict[str, float]
    post_mean_mm: dict[str, float]
    post_sd_mm: dict[str, float]
    gain_mm_per_mm: dict[str, float]
    dead_time_s: dict[str, float]
    time_constant_s: dict[str, float]


def _by_gauge(values: tuple[float, ...]) -> dict[str, float]:
    return dict(zip(GAUGES, values, strict=True))


TABLE_2 = StepTable(
    "A", 29.5, 15.0, 20.0,
    pre_mean_mm=_by_gauge((226.6, 231.7, 231.6, 235.3, 238.0)),
    pre_sd_mm=_by_gauge((0.32, 0.33, 0.35, 0.39, 0.38)),
    post_mean_mm=_by_gauge((149.6, 154.6, 155.3, 158.2, 161.1)),
    post_sd_mm=_by_gauge((2.33, 2.41, 2.42, 2.43, 2.42)),
    gain_mm_per_mm=_by_gauge((-15.41, -15.42, -15.27, -15.41, -15.39)),
    dead_time_s=_by_gauge((5.7, 4.5, 4.5, 4.5, 4.5)),
    time_constant_s=_by_gauge((71.5, 71.1, 71.2, 71.5, 70.8)),
)  # fmt: skip

TABLE_3 = StepTable(
    "B", 72.5, 30.0, 35.0,
    pre_mean_mm=_by_gauge((337.6, 342.1, 340.5, 346.6, 348.0)),
    pre_sd_mm=_by_gauge((1.12, 1.08, 0.59, 1.28, 0.63)),
    post_mean_mm=_by_gauge((283.9, 288.6, 288.2, 293.2, 295.9)),
    post_sd_mm=_by_gauge((1.46, 1.44, 1.39, 1.61, 1.88)),
    gain_mm_per_mm=_by_gauge((-10.75, -10.71, -10.46, -10.69, -10.43)),
    dead_time_s=_by_gauge((10.3, 9.2, 8.0, 10.3, 9.2)),
    time_constant_s=_by_gauge((41.1, 42.2, 43.3, 42.2, 43.3)),
)  # fmt: skip

STEP_TABLES = {"A": TABLE_2, "B": TABLE_3}


@dataclass(frozen=True)
class ArxRow:
    """Table 4: ARX(2,2,1) at gauge 3F."""

    condition: str
    flow_m3h: float
    a: tuple[float, float]
    b: tuple[float, float]
    r2: float
    mae_mm: float
    rmse_mm: float


TABLE_4 = {
    "C": ArxRow("C", 41.5, (0.713, 0.248), (-1.93, 1.17), 0.992, 0.65, 1.04),
    "D": ArxRow("D", 84.5, (0.575, 0.148), (-2.53, -0.51), 0.946, 1.42, 1.85),
}


@dataclass(frozen=True)
class StaticGainRow:
    """Table 5: static gain at 3F from quasi-steady data vs the step-identified gain."""

    condition: str
    static_flow_m3h: float
    step_flow_m3h: float
    opening_before_mm: float
    opening_after_mm: float
    static_dh3_mm: float
    static_gain_mm_per_mm: float
    step_gain_mm_per_mm: float


TABLE_5 = {
    "A": StaticGainRow("A", 26.3, 29.5, 15.0, 20.0, -79.5, -15.9, -15.4),
    "B": StaticGainRow("B", 68.1, 72.5, 30.0, 35.0, -54.6, -10.9, -10.6),
}
