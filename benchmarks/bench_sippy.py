"""gatetwin's ARX, ARMAX and OE fits side by side with SIPPY's, on bundled records C and D.

SIPPY (Systems Identification Package for Python, University of Pisa) is a peer
implementation; it is **not** a gatetwin dependency. Install it only to run this script::

    python -m pip install sippy-unipi

Run: ``python benchmarks/bench_sippy.py [--repeats 5]``.

Apples to apples:

* **Data.** Gauge 3F prepared exactly as :func:`gatetwin.identification.identify_prbs` does
  (opening reconstructed during actuator motion, all rows, Hampel spike correction), the
  same samples, demeaned by the same operating point (means over the samples used);
  SIPPY is called with ``centering="None"`` on these deviations.
* **Orders and delay.** gatetwin ARX(na=2, nb=2, nk=1), ARMAX(na=2, nb=2, nc=2, nk=1),
  OE(nf=2, nb=2, nk=1). SIPPY's delay ``theta`` counts samples *beyond* the one every
  model has (its first input regressor is ``u(k-1-theta)``), so ``theta = nk - 1 = 0``;
  its orders are ``ARX_orders=[na, nb, theta]``, ``ARMAX_orders=[na, nb, nc, theta]``,
  ``OE_orders=[nb, nf, theta]``.
* **Signs.** SIPPY writes ``A(q) = 1 + a1 q^-1 + ...`` (Ljung); gatetwin writes the
  reference study's ``y(k) = a1 y(k-1) + ...``, i.e. ``A(q) = 1 - a1 q^-1 - ...``. SIPPY's
  denominators are negated before printing, so the columns compare like with like.
  ``B`` and ``C = 1 + c1 q^-1 + ...`` have the same sign in both.
* **Metrics.** Both sets of coefficients are scored by the same gatetwin code: one-step
  R² of the structure's own predictor on the fit rows (for OE the predictor is the
  simulation), and free-run fit % on the last 30 % of the record by a model fitted on the
  first 70 % (the free run of :func:`gatetwin.identification.free_run_on_segments`).
* **Time.** Wall time of the fit call on the whole record, median of ``--repeats`` calls
  (SIPPY's messages to stdout are silenced during the calls).

Methods: SIPPY ARX by linear least squares (``ARX_mod="LLS"``), ARMAX by its iterative
linear least squares (``ARMAX_mod="ILLS"``, pseudo-linear regression), OE by its
optimisation method (``OE_mod="OPT"``, CasADi/IPOPT); gatetwin ARX by the normal
equations, ARMAX and OE by Levenberg-Marquardt on the prediction errors
(:mod:`gatetwin.identification.pem`).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import statistics
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gatetwin.bundled import bundled_records_dir
from gatetwin.identification.armax import fit_armax
from gatetwin.identification.arx import ArxFit, deviations, fit_arx
from gatetwin.identification.metrics import free_run_on_segments, one_step_metrics
from gatetwin.identification.oe import fit_oe
from gatetwin.identification.pem import PemOrders, one_step_prediction
from gatetwin.identification.prbs import PrbsSignals, prbs_signals
from gatetwin.records import read_record

NA, NB, NC, NK = 2, 2, 2, 1
ORDERS = {
    "ARX": PemOrders("arx", NA, NB, NK),
    "ARMAX": PemOrders("armax", NA, NB, NK, nc=NC),
    "OE": PemOrders("oe", NA, NB, NK),
}
INSTALL = "python -m pip install sippy-unipi"


def import_sippy() -> Any:
    """SIPPY's ``system_identification`` and python-control's ``tfdata``, or exit."""
    try:
        from control import tfdata
        from sippy_unipi import system_identification
    except ImportError:
        sys.exit(f"bench_sippy: SIPPY is not installed (benchmark only): {INSTALL}")
    return system_identification, tfdata


@dataclass(frozen=True)
class Segment:
    """Demeaned deviations of one segment and its operating point."""

    u0: np.ndarray
    y0: np.ndarray
    point: tuple[float, float]


def demeaned(sig: PrbsSignals, segments: np.ndarray) -> Segment:
    """Deviations over a single clean segment, with gatetwin's operating point."""
    if len(segments) != 1:
        raise SystemExit("bench_sippy: expected one segment per part (records C and D)")
    dev = deviations(sig.u, sig.y, segments)
    start, stop = segments[0]
    return Segment(dev.u0[start:stop], dev.y0[start:stop], (dev.opening_mean_mm, dev.level_mean_mm))


def sippy_theta(sippy: Any, method: str, seg: Segment) -> np.ndarray:
    """SIPPY fit, converted to gatetwin's ``theta`` (signs and delay as the docstring)."""
    system_identification, tfdata = sippy
    kwargs = {
        "ARX": {"ARX_orders": [NA, NB, NK - 1]},
        "ARMAX": {"ARMAX_orders": [NA, NB, NC, NK - 1], "ARMAX_mod": "ILLS"},
        "OE": {"OE_orders": [NB, NA, NK - 1], "OE_mod": "OPT"},
    }[method]
    with contextlib.redirect_stdout(io.StringIO()):
        model = system_identification(seg.y0, seg.u0, method, centering="None", **kwargs)
    num, den = (np.asarray(v[0][0], dtype=float) for v in tfdata(model.G))
    num, den = num / den[0], den / den[0]
    padded = np.concatenate((np.zeros(den.size - num.size), num))  # q^-j coefficients
    theta = [-den[1 : NA + 1], padded[NK : NK + NB]]
    if method == "ARMAX":
        num_h = np.asarray(tfdata(model.H)[0][0][0], dtype=float)
        theta.append(num_h[1 : NC + 1] / num_h[0])
    return np.concatenate(theta)


def gatetwin_theta(method: str, sig: PrbsSignals, segments: np.ndarray) -> np.ndarray:
    """gatetwin's fit of the same rows, as ``theta``."""
    u, y, ts = sig.u, sig.y, sig.sample_period_s
    if method == "ARX":
        return fit_arx(u, y, segments, NA, NB, NK, sample_period_s=ts).theta
    if method == "ARMAX":
        return fit_armax(u, y, segments, NA, NB, NC, NK, sample_period_s=ts).theta
    return fit_oe(u, y, segments, NA, NB, NK, sample_period_s=ts).theta


@dataclass(frozen=True)
class Scores:
    theta: np.ndarray
    r2: float
    free_run_percent: float
    seconds: float


def score(
    method: str, sig: PrbsSignals, theta: np.ndarray, theta_est: np.ndarray, seconds: float
) -> Scores:
    """One-step R² (whole record) and hold-out free-run fit % by gatetwin's metrics."""
    orders = ORDERS[method]
    full, est = demeaned(sig, sig.fit_segments), demeaned(sig, sig.estimation)
    dev = deviations(sig.u, sig.y, sig.fit_segments, full.point)
    pred = one_step_prediction(orders, theta, dev) + full.point[1]
    zeros = (0.0,) * NA, (0.0,) * NB
    model = ArxFit(
        NA,
        NB,
        NK,
        tuple(theta_est[:NA]),
        tuple(theta_est[NA : NA + NB]),
        *zeros,
        covariance=((0.0,),),
        noise_variance_mm2=0.0,
        n_rows=0,
        opening_mean_mm=est.point[0],
        level_mean_mm=est.point[1],
    )
    free = free_run_on_segments(model, sig.u, sig.y, sig.validation)[1]
    return Scores(theta, one_step_metrics(sig.y, pred).r2, free.fit_percent, seconds)


def median_seconds(func: Callable[[], Any], repeats: int) -> tuple[float, Any]:
    """Median wall time of ``repeats`` calls, s, and the last result."""
    times, out = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        out = func()
        times.append(time.perf_counter() - start)
    return statistics.median(times), out


def compare(sippy: Any, method: str, sig: PrbsSignals, repeats: int) -> tuple[Scores, Scores]:
    """(gatetwin, SIPPY) scores of one method on one record."""
    full, est = demeaned(sig, sig.fit_segments), demeaned(sig, sig.estimation)
    t_ours, ours = median_seconds(lambda: gatetwin_theta(method, sig, sig.fit_segments), repeats)
    t_peer, peer = median_seconds(lambda: sippy_theta(sippy, method, full), repeats)
    ours_est = gatetwin_theta(method, sig, sig.estimation)
    peer_est = sippy_theta(sippy, method, est)
    return (score(method, sig, ours, ours_est, t_ours), score(method, sig, peer, peer_est, t_peer))


def _coefficients(theta: np.ndarray) -> str:
    return " ".join(f"{v:+.4f}" for v in theta)


def _ratio(a: float, b: float) -> str:
    return f"{a / b:.2f}" if b != 0 else "n/a"


def report(name: str, method: str, ours: Scores, peer: Scores) -> None:
    """Print one method's rows: coefficients, R², free-run fit, time, and the ratios."""
    label = {"ARX": "a1 a2 | b1 b2", "ARMAX": "a1 a2 | b1 b2 | c1 c2", "OE": "f1 f2 | b1 b2"}[
        method
    ]
    print(f"\n{name} {method} ({label}; gatetwin signs: y(k) = a1 y(k-1) + ...)")
    for who, s in (("gatetwin", ours), ("SIPPY", peer)):
        print(f"  {who:9s} {_coefficients(s.theta)}")
        print(
            f"  {'':9s} one-step R2 {s.r2:.4f}   free-run fit {s.free_run_percent:6.1f} %"
            f"   time {1e3 * s.seconds:9.2f} ms"
        )
    print(
        f"  ratio gatetwin/SIPPY: R2 {_ratio(ours.r2, peer.r2)}, free-run fit "
        f"{_ratio(ours.free_run_percent, peer.free_run_percent)}, time "
        f"{_ratio(ours.seconds, peer.seconds)}; max |coefficient difference| "
        f"{np.max(np.abs(ours.theta - peer.theta)):.2e}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="timing repeats (median)")
    args = parser.parse_args()
    sippy = import_sippy()
    print("gatetwin vs SIPPY on gauge 3F; orders ARX(2,2,1), ARMAX(2,2,2,1), OE(2,2,1);")
    print("SIPPY delay theta = nk - 1 = 0; SIPPY's A/F signs negated to gatetwin's;")
    print("both scored by gatetwin's metrics (one-step R2 whole record; free run on the")
    print(f"last 30 % by a model fitted on the first 70 %); time: median of {args.repeats}")
    for name in ("C", "D"):
        record = read_record(Path(bundled_records_dir()) / f"{name}.csv")
        sig = prbs_signals(record, "3F", rows="auto", holdout_fraction=0.3, spike_floor_mm=0.0)
        for method in ORDERS:
            report(name, method, *compare(sippy, method, sig, args.repeats))


if __name__ == "__main__":
    main()
