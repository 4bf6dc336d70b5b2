"""Exception types of the dynamics package (python-control style: they subclass ValueError)."""


class SceneError(ValueError):
    """A scene file or scene dictionary is invalid; the message names the file and the key."""


class SimulationError(ValueError):
    """A run stopped: the state turned non-finite or a constraint error passed its threshold.

    Attributes
    ----------
    t_s : float
        Time of the failure, s.
    member : str
        The node, bar or joint at fault.
    partial : object or None
        The run up to the last good sample (a :class:`gyrotensegrity.runfile.Run`), if any.
    """

    def __init__(self, message: str, t_s: float, member: str, partial=None):
        super().__init__(message)
        self.t_s = t_s
        self.member = member
        self.partial = partial
