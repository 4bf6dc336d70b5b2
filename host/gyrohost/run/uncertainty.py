"""Standard deviations of what the ``nodes`` stream logs: node coordinates and the plane tilt.

The scene's node positions are linear in the filter's node coordinates ``q`` (``N = N_fix +
q U^T``, :meth:`TensegrityEKF.batch_nodes`), so their covariance is ``J P_qq J^T`` exactly,
with ``J`` the node positions' change per unit of each ``q`` entry (found once, by putting unit
vectors through ``batch_nodes``). The plane tilt is not linear in the nodes: its standard
deviation is that of its linearisation, ``g^T J P_qq J^T g`` with ``g`` its gradient in the
node positions (central differences, :data:`TILT_STEP_M`), about the estimate.
"""

import numpy as np

TILT_STEP_M = 1e-6
"""Node displacement of the tilt's central differences, m (round-off about 1e-10 rad)."""


class NodeSigma:
    """Standard deviations of scene node coordinates and plane tilt of a filter's estimate.

    Parameters
    ----------
    ekf : TensegrityEKF
    scene_cols : sequence of int
        Columns of the scene nodes (scene order) in the model's node matrix.
    tilt : TiltMeter or None
        The scene's attitude measure (None: no tilt).
    """

    def __init__(self, ekf, scene_cols, tilt=None):
        L = ekf.layout
        self.q, self.tilt = L.q, tilt
        n_q = L.q.stop - L.q.start
        X = np.zeros((n_q + 1, L.size))
        X[1:, L.q] = np.eye(n_q)
        N, _ = ekf.batch_nodes(X)
        N = N[:, :, list(scene_cols)]
        # rows: scene node i, axis a at i * 3 + a (the nodes stream's column order)
        self.J = (N[1:] - N[0]).transpose(0, 2, 1).reshape(n_q, -1).T
        n = N.shape[2]
        steps = TILT_STEP_M * np.eye(3 * n).reshape(3 * n, n, 3).transpose(0, 2, 1)
        self._steps = np.concatenate([steps, -steps])  # ahead, then behind: one batch

    def node_covariance(self, P):
        """Covariance (3 n, 3 n), m^2, of the scene node coordinates (node-major, x y z)."""
        P_qq = np.asarray(P)[self.q, self.q]
        return self.J @ P_qq @ self.J.T

    def tilt_gradient(self, N):
        """Gradient (3 n,), rad/m, of the plane tilt in the scene node coordinates ``N`` (3, n)."""
        ahead, behind = np.split(self.tilt.tilt(N + self._steps), 2)
        return (ahead - behind) / (2.0 * TILT_STEP_M)

    def std(self, N, P) -> tuple[np.ndarray, tuple]:
        """Standard deviations of the node coordinates (3 n,), m, and the cells of the tilt's,
        rad (none without a tilt measure), for nodes ``N`` (3, n) m and filter covariance ``P``."""
        C = self.node_covariance(P)
        node_std = np.sqrt(np.clip(np.diag(C), 0.0, None))
        if self.tilt is None:
            return node_std, ()
        g = self.tilt_gradient(N)
        return node_std, (float(np.sqrt(max(g @ C @ g, 0.0))),)
