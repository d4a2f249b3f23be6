"""Coordinate partitioning (Wehage and Haug 1982): which coordinates are dependent,
how well conditioned their block of the constraint Jacobian is, and the solves with
it; dense (column-pivoted QR) and sparse (SuperLU with partial pivoting of ``G^T``,
Higham and Tisseur's 1-norm estimate) alike. Used by the ``partitioning``
formulation (:mod:`integrator_bench.problems.formulations`)."""

from __future__ import annotations

import numpy as np
import scipy.linalg
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from integrator_bench.problems.linalg import splu


class DensePartition:
    """Coordinate partition of a dense G: dependent columns by column-pivoted QR
    (Businger and Golub 1965), conditioning ``||G||_2 ||G_dep^-1||_2`` by SVD."""

    @staticmethod
    def dependent(G, nc):
        return np.sort(scipy.linalg.qr(G, pivoting=True, mode="r")[1][:nc])

    @staticmethod
    def conditioning(G, dep):
        # ||G|| ||G_dep^-1||: cond(G_dep) alone is 1 for any nonzero 1x1 block
        return np.linalg.norm(G, 2) / np.linalg.svd(G[:, dep], compute_uv=False)[-1]

    @staticmethod
    def solve(G, dep, r):
        """``G_dep^-1 r``."""
        return np.linalg.solve(G[:, dep], r)

    @staticmethod
    def columns(G, idx):
        return G[:, idx]


class SparsePartition:
    """Coordinate partition of a sparse G without a dense matrix.

    The dependent columns come from Gaussian elimination of G, constraint row
    by constraint row, with column pivoting: each row, reduced by the pivots
    before it, takes the column of largest magnitude as its pivot, and that
    column is eliminated from the rows below that hold it (LU with partial
    pivoting of ``G^T``; Wehage and Haug 1982 pivot fully, also reordering the
    constraints; either gives a non-singular ``G_dep`` when G has full row
    rank). A row without a pivot above 1e-12 of G's largest entry stops the
    choice short (G rank deficient). The reduced rows fill in: for a chain the
    dependent positions hang on every angle before them, so the reduced row
    of joint i holds all earlier angles, and a stored LU holds O(nc^2)
    entries (SuperLU on ``G^T`` completed to the square ``[[G^T, I], [eps I,
    0]]``: 1.5 million in each of L and U for a 1000-link chain). Only
    the pivots are needed, so each row is kept as a dense vector from the
    moment an elimination first touches it until it has given its pivot, and
    then dropped: the memory is that of the rows touched and not yet
    reduced (a few for constraints numbered along a chain), the work
    O(nc nq) in vector operations. The conditioning is
    ``||G||_1 ||G_dep^-1||_1`` with the inverse's norm estimated by Higham and
    Tisseur's block 1-norm estimator (SIAM J. Matrix Anal. Appl. 21 (2000)
    1185-1201; ``onenormest`` with one column, deterministic) from the sparse
    LU of ``G_dep``.
    """

    @staticmethod
    def dependent(G, nc):
        G, nq = sp.csr_matrix(G), G.shape[1]
        holders = sp.csc_matrix(G)         # original rows holding each column
        tol = 1e-12 * abs(G).max()
        touched, dep = {}, []

        def dense_row(i):
            row = np.zeros(nq)
            row[G.indices[G.indptr[i]:G.indptr[i + 1]]] = G.data[G.indptr[i]:G.indptr[i + 1]]
            return row

        for i in range(nc):
            row = touched.pop(i, None)
            if row is None:
                row = dense_row(i)
            j = int(np.argmax(np.abs(row)))
            if abs(row[j]) <= tol:
                break
            dep.append(j)
            below = holders.indices[holders.indptr[j]:holders.indptr[j + 1]]
            for r in set(below[below > i].tolist()) | {r for r in touched if touched[r][j]}:
                target = touched.get(r)
                if target is None:
                    target = touched[r] = dense_row(r)
                target -= (target[j] / row[j]) * row
                target[j] = 0.0
        return np.sort(np.array(dep, dtype=int))

    @staticmethod
    def _factor(G, dep):
        return splu(sp.csc_matrix(G)[:, dep])

    @staticmethod
    def conditioning(G, dep):
        lu = SparsePartition._factor(G, dep)
        inverse = spla.LinearOperator(lu.shape, matvec=lu.solve, dtype=float,
                                      rmatvec=lambda x: lu.solve(x, trans="T"))
        return spla.norm(G, 1) * spla.onenormest(inverse, t=1)

    @staticmethod
    def solve(G, dep, r):
        """``G_dep^-1 r`` by sparse LU."""
        return SparsePartition._factor(G, dep).solve(r)

    @staticmethod
    def columns(G, idx):
        return sp.csc_matrix(G)[:, idx]
