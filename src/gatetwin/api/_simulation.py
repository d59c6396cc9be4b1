"""Simulating a model on given inputs, and the result as arrays, a table and a figure.

The stepping is the plant's Python reference simulation
(:func:`gatetwin.plant.simulate.simulator_for`); this module only shapes the inputs and
the output for interactive use.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from gatetwin.errors import GatetwinError

if TYPE_CHECKING:  # the plant package pulls in scipy: imported where it is used
    from gatetwin.plant.model import Plant

__all__ = ["SimulationResult", "require_pandas", "simulate_plant"]


def require_pandas() -> Any:
    """The pandas module, or a one-line :class:`GatetwinError` saying it is missing."""
    try:
        import pandas
    except ImportError:
        raise GatetwinError(
            "to_pandas() needs pandas, which is not installed (pip install pandas)"
        ) from None
    return pandas


def _read_only(values: np.ndarray) -> np.ndarray:
    out = np.array(values, dtype=float)
    out.setflags(write=False)
    return out


@dataclass(frozen=True, eq=False)
class SimulationResult:
    """A model's level over time for given inputs.

    Attributes
    ----------
    model : str
        Name of the model simulated.
    gauge : str
        Gauge of the output (``level_<gauge>_mm``).
    time_s : ndarray
        Sample times, s.
    opening_mm : ndarray
        Gate opening held from each sample to the next, mm.
    flow_m3h : ndarray
        Discharge held from each sample to the next, m³/h.
    level_mm : ndarray
        Simulated level at each sample time, mm.

    Examples
    --------
    >>> from gatetwin import bundled_records_dir, identify
    >>> model = identify(bundled_records_dir() / "A.csv")
    >>> result = model.simulate([15.0] * 50 + [20.0] * 250, 29.5, sample_period_s=1.2)
    >>> float(result.time_s[-1])
    358.8
    >>> bool(result.level_mm[-1] < result.level_mm[0])  # opening the gate lowers the level
    True
    """

    model: str
    gauge: str
    time_s: np.ndarray = field(repr=False)
    opening_mm: np.ndarray = field(repr=False)
    flow_m3h: np.ndarray = field(repr=False)
    level_mm: np.ndarray = field(repr=False)

    @property
    def level_column(self) -> str:
        """The record-format name of the output column, ``level_<gauge>_mm``."""
        return f"level_{self.gauge}_mm"

    def to_pandas(self) -> Any:
        """The signals as a :class:`pandas.DataFrame` with the record format's column names.

        Returns
        -------
        pandas.DataFrame
            Columns ``time_s``, ``opening_mm``, ``flow_m3h`` and ``level_<gauge>_mm``.

        Raises
        ------
        GatetwinError
            pandas is not installed.

        Examples
        --------
        >>> from gatetwin import bundled_records_dir, identify
        >>> model = identify(bundled_records_dir() / "A.csv")
        >>> frame = model.simulate([15.0, 20.0, 20.0], 29.5, sample_period_s=1.2).to_pandas()
        >>> list(frame.columns)
        ['time_s', 'opening_mm', 'flow_m3h', 'level_3F_mm']
        """
        pandas = require_pandas()
        return pandas.DataFrame({"time_s": self.time_s, "opening_mm": self.opening_mm,
                                 "flow_m3h": self.flow_m3h,
                                 self.level_column: self.level_mm})  # fmt: skip

    def plot(self, ax: Any = None) -> Any:
        """Level over time (and, without ``ax``, the opening below it).

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Draw the level there; default a new figure with the level and the opening.

        Returns
        -------
        matplotlib.figure.Figure

        Examples
        --------
        >>> from gatetwin import bundled_records_dir, identify
        >>> model = identify(bundled_records_dir() / "A.csv")
        >>> fig = model.simulate([15.0, 20.0, 20.0], 29.5, sample_period_s=1.2).plot()
        >>> [a.get_ylabel() for a in fig.axes]
        ['level_3F_mm (mm)', 'opening (mm)']
        >>> import matplotlib.pyplot as plt; plt.close(fig)
        """
        import matplotlib.pyplot as plt

        if ax is not None:
            ax.plot(self.time_s, self.level_mm, label=self.model)
            return ax.figure
        fig, (top, bottom) = plt.subplots(2, 1, sharex=True, figsize=(8, 5),
                                          height_ratios=(2, 1))  # fmt: skip
        top.plot(self.time_s, self.level_mm, label=self.model)
        top.set_ylabel(f"{self.level_column} (mm)")
        top.legend(loc="best")
        bottom.step(self.time_s, self.opening_mm, where="post")
        bottom.set_ylabel("opening (mm)")
        bottom.set_xlabel("time (s)")
        return fig


def _time_axis(n_inputs: int, time_s: Any, sample_period_s: float | None,
               plant: Plant) -> np.ndarray:  # fmt: skip
    from gatetwin.plant.inputs import SimulationError
    from gatetwin.plant.model import ArxPlant

    if time_s is not None and sample_period_s is not None:
        raise SimulationError("give time_s or sample_period_s, not both")
    if time_s is not None:
        t = np.asarray(time_s, dtype=float)
        if t.ndim != 1 or t.size < 2:
            raise SimulationError("time_s: expected a 1-D array of at least 2 sample times")
        bad = np.flatnonzero(~np.isfinite(t) | np.r_[False, np.diff(t) <= 0])
        if bad.size:
            raise SimulationError(f"time_s[{bad[0]}] = {t[bad[0]]}: times must be finite and "
                                  "strictly increasing")  # fmt: skip
        return t
    if sample_period_s is None:
        if not isinstance(plant, ArxPlant):
            raise SimulationError("give time_s or sample_period_s (the model has no own "
                                  "sample period)")  # fmt: skip
        sample_period_s = plant.sample_period_s
    if not (isinstance(sample_period_s, (int, float)) and math.isfinite(sample_period_s)
            and sample_period_s > 0):  # fmt: skip
        raise SimulationError(f"sample_period_s = {sample_period_s!r}: expected a number > 0")
    if n_inputs < 2:
        raise SimulationError("with sample_period_s, give opening_mm or flow_m3h as an array "
                              "of at least 2 samples (or give time_s)")  # fmt: skip
    return np.round(np.arange(n_inputs) * float(sample_period_s), 9)


def _input(name: str, values: Any, n: int) -> np.ndarray:
    from gatetwin.plant.inputs import SimulationError

    x = np.asarray(values, dtype=float)
    if x.ndim == 0:
        x = np.full(n, float(x))
    if x.shape != (n,):
        raise SimulationError(f"{name}: expected a number or {n} samples, got shape {x.shape}")
    bad = np.flatnonzero(~np.isfinite(x))
    if bad.size:
        raise SimulationError(f"{name}[{bad[0]}] is {x[bad[0]]}; inputs must be finite")
    return x


def simulate_plant(
    plant: Plant, name: str, opening_mm: Any, flow_m3h: Any, time_s: Any,
    sample_period_s: float | None, level0: float | None,
) -> SimulationResult:  # fmt: skip
    """Shape the inputs, run the reference simulation, shift to ``level0`` if given."""
    from gatetwin.plant.inputs import SimulationError
    from gatetwin.plant.simulate import simulate

    sizes = [np.size(v) for v in (opening_mm, flow_m3h) if np.ndim(v) > 0]
    t = _time_axis(max(sizes, default=0), time_s, sample_period_s, plant)
    e = _input("opening_mm", opening_mm, t.size)
    q = _input("flow_m3h", flow_m3h, t.size)
    level = simulate(plant, t, e, q)
    if level0 is not None:
        if not math.isfinite(level0):
            raise SimulationError(f"level0 = {level0!r}: expected a finite level in mm")
        level = level + (float(level0) - level[0])
    return SimulationResult(name, plant.gauge, _read_only(t), _read_only(e), _read_only(q),
                            _read_only(level))  # fmt: skip
