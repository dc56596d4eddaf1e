"""tfs: sparse equations of motion for nonlinear multi-stable structures from noisy vibration data.

The same library as the ``tfs`` command-line tool (T-F-S SINDy and classical SINDy, simulation,
diagnosis, basins of attraction, the Kresling simulators), with numpy arrays in and out::

    import tfs
    recs = tfs.simulate_kresling(gamma0=30, snr_db=30, duration=40)
    model = tfs.identify(recs, library="x^1..7, x', xb_acc")
    model.print()
    x, v = model.simulate(recs[0].t, recs[0]["xb_acc"], x0=[recs[0]["x"][0]])
"""

from ._tfs import (
    Model,
    Record,
    __version__,
    basin,
    diagnose,
    identify,
    kresling,
    load,
    med,
    simulate_chain,
    simulate_kresling,
)
from ._results import Comparison
from .errors import InputError, SimulationError, TfsError

__all__ = [
    "Model",
    "Record",
    "Comparison",
    "identify",
    "load",
    "diagnose",
    "basin",
    "med",
    "kresling",
    "simulate_kresling",
    "simulate_chain",
    "TfsError",
    "InputError",
    "SimulationError",
    "__version__",
]
