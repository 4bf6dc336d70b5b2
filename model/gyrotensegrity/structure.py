"""Structure compiler: node matrix layout, connectivity and constraint matrices of a scene.

Nodes are laid out as in the paper (Section IV): ``N = [N1 N2 Ns]`` with bar ``i`` running
from node ``i`` (in ``N1``) to node ``beta + i`` (in ``N2``), then the string-to-string nodes
``Ns``. Each bar end is a node of its own; a scene node shared by ``k`` bars (a class-k joint)
becomes ``k`` nodes: the first in node order is its *primary* node, the other ``k - 1`` are
*virtual* nodes held on it by the constraint ``N P = D`` (Eq. 60). A fixed scene node adds a
column to ``P`` that pins its primary node at its scene position. Strings, point masses and
external forces attach to primary nodes.
"""

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .scene import Scene


@dataclass(frozen=True)
class Structure:
    """Connectivity of a scene (all matrices sparse, CSR).

    Attributes
    ----------
    node_names : list of str, (n,)
        Scene node each node coincides with (virtual nodes repeat their scene node's name).
    is_virtual : ndarray of bool, shape (n,)
    primary : dict of str to int
        Node index of each scene node's primary node.
    N0, N0_dot : ndarray, shape (3, n), m and m/s
        Initial node positions and velocities.
    bar_start, bar_end : ndarray of int, shape (beta,)
    string_start, string_end : ndarray of int, shape (alpha,)
    C_b, C_r : sparse, shape (beta, n)
        Bar connectivity (-1 start, +1 end) and centre matrix (1/2, 1/2).
    C_s : sparse, shape (alpha, n)
        String connectivity (-1 start, +1 end).
    C_nb, C_ns : sparse, shape (2 beta, n) and (sigma, n)
        Selectors of the bar nodes and of the string-to-string nodes (Eqs. 43-44).
    P : sparse, shape (n, c); D : ndarray, shape (3, c), m
        Constraints ``N P = D`` (Eq. 60).
    constraint_names : list of str, (c,)
    constraint_groups : list of (nodes, columns)
        Node indices and P columns of each scene node with constraints; P is block diagonal
        over these groups, which the SVD of Eq. 63 uses.
    """

    node_names: list
    is_virtual: np.ndarray
    primary: dict
    N0: np.ndarray
    N0_dot: np.ndarray
    bar_start: np.ndarray
    bar_end: np.ndarray
    string_start: np.ndarray
    string_end: np.ndarray
    C_b: sp.csr_matrix
    C_r: sp.csr_matrix
    C_s: sp.csr_matrix
    C_nb: sp.csr_matrix
    C_ns: sp.csr_matrix
    P: sp.csr_matrix
    D: np.ndarray
    constraint_names: list
    constraint_groups: list

    @property
    def n(self) -> int:
        return len(self.node_names)

    @property
    def c(self) -> int:
        return self.P.shape[1]


def _incidence(start, end, n) -> sp.csr_matrix:
    rows = np.repeat(np.arange(len(start)), 2)
    cols = np.column_stack([start, end]).ravel()
    vals = np.tile([-1.0, 1.0], len(start))
    return sp.csr_matrix((vals, (rows, cols)), shape=(len(start), n))


def _selector(indices, n) -> sp.csr_matrix:
    k = len(indices)
    return sp.csr_matrix((np.ones(k), (np.arange(k), indices)), shape=(k, n))


def compile_structure(scene: Scene) -> Structure:
    """Lay out the nodes of ``scene`` and build C_b, C_r, C_s, C_nb, C_ns, P and D."""
    beta = len(scene.bars)
    bar_scene_nodes = [b.start for b in scene.bars] + [b.end for b in scene.bars]
    string_only = [
        name for name in scene.node_names if name not in set(bar_scene_nodes)
    ]  # the string-to-string nodes (and fixed anchors), in scene order
    node_names = bar_scene_nodes + string_only
    n = len(node_names)

    members: dict[str, list[int]] = {}
    for i, name in enumerate(node_names):
        members.setdefault(name, []).append(i)
    primary = {name: idx[0] for name, idx in members.items()}
    is_virtual = np.array([primary[name] != i for i, name in enumerate(node_names)])

    scene_idx = [scene.node_index(name) for name in node_names]
    N0 = scene.positions[:, scene_idx]
    N0_dot = scene.velocities[:, scene_idx]

    bar_start, bar_end = np.arange(beta), beta + np.arange(beta)
    string_start = np.array([primary[s.start] for s in scene.strings], dtype=int)
    string_end = np.array([primary[s.end] for s in scene.strings], dtype=int)

    C_b = _incidence(bar_start, bar_end, n)
    C_r = abs(C_b) * 0.5
    C_s = _incidence(string_start, string_end, n)

    P_cols, D_cols, names, groups = [], [], [], []
    for name, idx in members.items():
        first = len(P_cols)
        for v in idx[1:]:
            P_cols.append({idx[0]: 1.0, v: -1.0})
            D_cols.append(np.zeros(3))
            names.append(f"joint {name} (node {idx[0]} = node {v})")
        if name in scene.fixed:
            P_cols.append({idx[0]: 1.0})
            D_cols.append(scene.positions[:, scene.node_index(name)])
            names.append(f"fixed {name}")
        if len(P_cols) > first:
            groups.append((np.array(idx), np.arange(first, len(P_cols))))
    rows = [r for col in P_cols for r in col]
    cols = [j for j, col in enumerate(P_cols) for _ in col]
    vals = [v for col in P_cols for v in col.values()]
    P = sp.csr_matrix((vals, (rows, cols)), shape=(n, len(P_cols)))
    D = np.column_stack(D_cols) if D_cols else np.zeros((3, 0))

    return Structure(
        node_names=node_names,
        is_virtual=is_virtual,
        primary=primary,
        N0=N0,
        N0_dot=N0_dot,
        bar_start=bar_start,
        bar_end=bar_end,
        string_start=string_start,
        string_end=string_end,
        C_b=C_b,
        C_r=sp.csr_matrix(C_r),
        C_s=C_s,
        C_nb=_selector(np.arange(2 * beta), n),
        C_ns=_selector(np.arange(2 * beta, n), n),
        P=P,
        D=D,
        constraint_names=names,
        constraint_groups=groups,
    )
