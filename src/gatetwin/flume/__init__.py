"""Virtual flume: a hydraulic simulation of the reference study's laboratory flume."""

from gatetwin.flume.config import PAPER_GAUGES_M, FlumeConfig, GateLaw
from gatetwin.flume.simulate import FlumeRun, run_flume, spin_up

__all__ = ["PAPER_GAUGES_M", "FlumeConfig", "FlumeRun", "GateLaw", "run_flume", "spin_up"]
