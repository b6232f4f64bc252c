"""The nine navigation error states, in the order of a filter's 1-sigma record
(:attr:`navsim.records.history.EstimatorHistory.sigma`'s last axis) and of the initial errors a
run draws: attitude, velocity, position, each about N, E, D; and their blocks as named slices.
"""

from __future__ import annotations

#: the states of :attr:`~navsim.records.history.EstimatorHistory.sigma`'s last axis
SIGMA_STATES = ("att_N", "att_E", "att_D", "vel_N", "vel_E", "vel_D", "pos_N", "pos_E", "pos_D")


def _block(name: str) -> slice:
    """The states of :data:`SIGMA_STATES` named ``<name>_*``, as one slice."""
    idx = [i for i, s in enumerate(SIGMA_STATES) if s.split("_")[0] == name]
    return slice(idx[0], idx[-1] + 1)


#: attitude error about N, E, D (rad)
ATT = _block("att")
#: velocity error N, E, D (m/s)
VEL = _block("vel")
#: position error N, E, D (m)
POS = _block("pos")
#: the horizontal position error, N and E (m)
POS_NE = slice(POS.start, POS.start + 2)
#: each block by its name
BLOCKS = {"att": ATT, "vel": VEL, "pos": POS}
#: the size of each named dimension of a record's arrays (``dims`` of
#: :data:`~navsim.records.history.ARRAYS`) other than the run and the epoch
DIM_SIZES = {"axis": 3, "state": len(SIGMA_STATES)}
