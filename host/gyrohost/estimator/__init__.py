"""State estimation for the rig: an EKF on the gyroscopic tensegrity dynamics (docs/estimator.md).

Modules: :mod:`.ekf` (the filter, status word), :mod:`.process_model` (discrete dynamics and
Jacobian), one ``fuse_*`` module per measurement source, :mod:`.fusion` (innovation, NIS, gate),
:mod:`.timeouts`, :mod:`.manifold` (constraints), :mod:`.streams` (log columns shared with the
run loop), :mod:`.replay`, :mod:`.synthetic` and :mod:`.montecarlo` (consistency checks).
"""

from .config import EstimatorConfig, config_from_dict, load_config
from .ekf import Status, TensegrityEKF
from .errors import EstimatorConfigError, EstimatorError
from .fusion import Innovation

__all__ = [
    "EstimatorConfig",
    "EstimatorConfigError",
    "EstimatorError",
    "Innovation",
    "Status",
    "TensegrityEKF",
    "config_from_dict",
    "load_config",
]
