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


class PrunedTermError(ValueError):
    """A call needs a model term that the model was built without.

    Raised instead of silently evaluating without the term, e.g. a wheel input or spin on a
    model built with ``Model(scene, omit=("gyroscopic",))``.

    Attributes
    ----------
    term : str
        The omitted term (one of :data:`gyrotensegrity.model.Model.ALL_TERMS`).
    member : str
        The bar whose wheel needs it.
    """

    def __init__(self, message: str, term: str, member: str):
        super().__init__(message)
        self.term = term
        self.member = member
