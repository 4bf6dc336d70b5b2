"""Where each wheel's motor reaction goes: to the whole structure, out of it, or into its own bar.

A wheel's motor turns the rotor about its bar's axis and pushes back on the stator, which sits on
the bar: the reaction is a torque about the bar's axis. What the structure makes of it depends on
what holds the bar's rotation about its own axis, read from the scene's joints and its
rig-fidelity option (docs/rig-fidelity.md):

``body``
    The bar meets another bar at a hinge, which carries a torque about the bar's axis (normal to
    the hinge axis) to the neighbour: the reaction turns the structure, the total angular
    momentum (wheels included) is kept. Rig fidelity with hinges and the motor's reaction
    (dbar-rig); a scene without the option whose bars meet other bars is taken as the rig it
    idealises (the paper's ball joints drop the reaction; the D-bar's plans are for the hinged
    rig, and are played there).
``lost``
    Nothing carries the reaction: the paper's model (no ``[rig_fidelity]``, or no
    ``motor_reaction``) of a bar that meets only strings. Strings pull along their own lines,
    through the bar's end on its axis, so they exert no moment about it; the wheel's spin is set
    by its motor and the reaction leaves the structure. The total angular momentum then changes
    by the wheel's: ``dH/dt = J_3 omega_w_dot b_hat``, and the structure itself feels the wheel
    only through its gyroscopic couple ``J_3 omega_w b_hat_dot`` (Eq. 27: no ``omega_w_dot``).
``own``
    Rig fidelity with the motor's reaction on a bar at no hinge: the reaction spins only that bar
    about its axis, whose axial momentum ``J_3 omega_w + J_s omega_ax`` stays as it was; the rest
    of the structure sees that constant momentum, whatever the wheel's speed: the wheel cannot
    steer (a planner holds it).
"""

import numpy as np

COUPLINGS = ("body", "lost", "own")


def wheel_couplings(model):
    """The coupling (one of :data:`COUPLINGS`) of each wheel, in ``model.wheel_bars`` order."""
    scene, spec = model.scene, model.scene.rig
    jointed = scene.jointed_bars()
    out = []
    for i in (int(i) for i in model.wheel_bars):
        if spec is None:
            out.append("body" if i in jointed else "lost")
        elif not spec.motor_reaction:
            out.append("lost")
        elif spec.joints == "hinge" and i in jointed:
            out.append("body")
        else:
            out.append("own")
    return tuple(out)


def coupling_mask(couplings, kind):
    """Boolean mask (n_w,) of the wheels of one coupling ``kind``."""
    return np.array([c == kind for c in couplings], dtype=bool)
