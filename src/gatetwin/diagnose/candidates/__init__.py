"""The library of candidate effects, one module per block kind (see :mod:`.base`)."""

from gatetwin.diagnose.candidates.backlash import BacklashCandidate
from gatetwin.diagnose.candidates.base import Candidate, Context
from gatetwin.diagnose.candidates.drift import DriftCandidate
from gatetwin.diagnose.candidates.flow_gain import FlowGainCandidate
from gatetwin.diagnose.candidates.inflow import InflowCandidate
from gatetwin.diagnose.candidates.lag import LagCandidate
from gatetwin.diagnose.candidates.nonlinearity import NonlinearityCandidate
from gatetwin.diagnose.candidates.rate_limit import RateLimitCandidate
from gatetwin.diagnose.candidates.seiche import SeicheCandidate

#: Every candidate, in the blocks' evaluation order.
CANDIDATES: tuple[Candidate, ...] = (
    RateLimitCandidate(),
    BacklashCandidate(),
    NonlinearityCandidate(),
    FlowGainCandidate(),
    SeicheCandidate(),
    InflowCandidate(),
    DriftCandidate(),
    LagCandidate(),
)

__all__ = ["CANDIDATES", "Candidate", "Context"]
