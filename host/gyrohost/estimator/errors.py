"""Exception types of the estimator."""

from gyrohost.errors import GyrohostError


class EstimatorConfigError(GyrohostError, ValueError):
    """An estimator configuration value or scene the estimator cannot use; names the key."""


class EstimatorError(GyrohostError, RuntimeError):
    """The filter cannot go on (non-finite state or covariance); names the time and member."""

    def __init__(self, message: str, t_s: float, member: str):
        super().__init__(message)
        self.t_s = t_s
        self.member = member

    def __reduce__(self):  # crosses the pipe from the run's estimator process whole
        return type(self), (str(self), self.t_s, self.member)
