"""The library of candidate effects, one module per block kind (see :mod:`.base`)."""

from gatetwin.diagnosis.candidates.backlash import BacklashCandidate
from gatetwin.diagnosis.candidates.base import Candidate, Context
from gatetwin.diagnosis.candidates.drift import DriftCandidate
from gatetwin.diagnosis.candidates.flow_gain import FlowGainCandidate
from gatetwin.diagnosis.candidates.inflow import InflowCandidate
from gatetwin.diagnosis.candidates.lag import LagCandidate
from gatetwin.diagnosis.candidates.nonlinearity import NonlinearityCandidate
from gatetwin.diagnosis.candidates.rate_limit import RateLimitCandidate
from gatetwin.diagnosis.candidates.seiche import SeicheCandidate

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
