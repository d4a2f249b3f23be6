"""Sparse Jacobians and iteration matrices for the implicit methods.

A system may give its Jacobian as a ``scipy.sparse`` matrix (``OdeSystem.jac``,
``DaeSystem.jac``, the blocks of ``MechanicalSystem``) or name its structural
non-zeros in ``jac_sparsity``. Large systems (thousands of states) must then
run without any dense ``n x n`` matrix: a 4000-state system has a 128 MB dense
Jacobian, a factorization of it costs ``n^3 / 3`` flops, and a 1000-link chain
(8000 DAE states) needs 512 MB per copy. This module holds what the implicit
methods share for that:

* :func:`factor`: the LU factorization of an iteration matrix, LAPACK
  ``getrf`` for a dense one (called directly, with ``getrs`` for the solves:
  ``scipy.linalg.lu_solve``'s checks and batching cost more than a small
  system's solve),
  SuperLU (``scipy.sparse.linalg.splu``, column
  ordering COLAMD) for a sparse one; a singular matrix gives a solve that
  returns NaN, so that the caller's test of a non-finite correction reports
  it, as LAPACK's singular factors do;
* :func:`identity_minus`: ``I - c J`` in the format of ``J``;
* :class:`SaddlePoint`: the saddle-point matrix ``[[sum_i c_i X_i, G^T], [G, 0]]``
  of the Newmark-family methods assembled in CSC straight from the blocks'
  stored entries, the sorting of the structure done once and redone only
  when a block's layout of stored entries changes (``scipy.sparse.bmat`` and
  sparse sums instead cost some twenty Python-level constructions and checks
  per matrix, half a factorization's time on the chain drive);
* :class:`GroupedDifferences`: a forward-difference Jacobian with the known
  sparsity pattern, one evaluation of ``f`` per group of structurally
  orthogonal columns (Curtis, Powell and Reid 1974; the greedy grouping of
  ``scipy.optimize._numdiff.group_columns`` in the natural column order,
  which gives ``ml + mu + 1`` groups for a banded pattern), never a dense one;
* :func:`pattern`, :func:`bandwidths`, :func:`on_pattern`: the structure of a
  sparse Jacobian for library codes that need it fixed before the run
  (SUNDIALS' sparse matrix, LSODA's band) and the values of a Jacobian laid out
  on that structure.

A dense Jacobian stays dense: these paths are taken only when the system gives
sparse matrices or a sparsity pattern. ``DENSE_LIMIT`` is the size above which
an integrator that could only densify a sparse system declines it (status
``method_limit``) instead of allocating ``n x n`` arrays.

References: A. R. Curtis, M. J. D. Powell, J. K. Reid, "On the estimation of
sparse Jacobian matrices", J. Inst. Math. Appl. 13 (1974) 117-119;
X. S. Li, "An overview of SuperLU", ACM TOMS 31 (2005) 302-325.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.linalg.lapack import dgetrf as _getrf, dgetrs as _getrs
from scipy.optimize._numdiff import group_columns

from integrator_bench.problems.system import DENSE_JACOBIAN_LIMIT

_EPS = np.finfo(float).eps
#: above this size a sparse system is not densified: the limit of
#: :mod:`integrator_bench.problems.system` for dense Jacobians (a dense copy is
#: 32 MB at 2000 states)
DENSE_LIMIT = DENSE_JACOBIAN_LIMIT


def dense(matrix) -> np.ndarray:
    """A matrix (a Jacobian, a block) as a dense array, whether it came dense or sparse."""
    return matrix.toarray() if sp.issparse(matrix) else np.asarray(matrix, float)


def factor(A, symmetric: bool = False):
    """``solve(b)`` with ``A x = b`` from an LU factorization of ``A``, dense or sparse.

    ``symmetric``: ``A`` is symmetric positive definite (``G G^T``): SuperLU then
    orders ``A + A^T`` by minimum degree and pivots on the diagonal
    (``SymmetricMode``), about half the time of the general COLAMD ordering
    with partial pivoting on a chain's ``G G^T``.
    """
    if sp.issparse(A):
        kw = (dict(permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                   options=dict(SymmetricMode=True)) if symmetric else {})
        try:
            return spla.splu(sp.csc_matrix(A), **kw).solve
        except RuntimeError:   # SuperLU: "Factor is exactly singular"
            return lambda b: np.full(np.shape(b), np.nan)
    lu, piv, _ = _getrf(A)     # info > 0: singular; the solves then give inf or NaN
    return lambda b: _getrs(lu, piv, b)[0]


def triplets(X):
    """``(rows, cols, data)`` of the stored entries of ``X`` (sparse, or dense:
    then all entries); CSR and CSC are read without a conversion."""
    if not sp.issparse(X):
        X = np.atleast_2d(np.asarray(X, float))
        rows, cols = np.indices(X.shape)
        return rows.ravel(), cols.ravel(), X.ravel()
    if X.format == "csr":
        return np.repeat(np.arange(X.shape[0]), np.diff(X.indptr)), X.indices, X.data
    if X.format == "csc":
        return X.indices, np.repeat(np.arange(X.shape[1]), np.diff(X.indptr)), X.data
    X = X.tocoo()
    return X.row, X.col, X.data


class SaddlePoint:
    """``[[sum_i c_i X_i, G^T], [G, 0]]`` in CSC, for square ``X_i`` (nq x nq) and
    ``G`` (nc x nq), dense or sparse.

    The stored entries of all blocks are gathered with their offsets, and
    entries at one position are summed; entries whose sum is exactly zero are
    dropped, as ``scipy.sparse`` sums drop them (so SuperLU sees the pattern it
    saw when the matrix was built from such sums). Where each gathered entry
    goes in the CSC arrays (a stable sort of the positions) is kept and reused
    while the blocks come with the same layout of stored entries, which is
    checked at every call (an O(nnz) comparison); the values are then placed
    by one ``bincount``.
    """

    def __init__(self, nq: int, nc: int):
        self.nq, self.nc = nq, nc
        self.n = nq + nc
        self.rows = self.cols = None

    def _layout(self, rows, cols):
        key = cols.astype(np.int64) * self.n + rows
        order = np.argsort(key, kind="stable")
        skey = key[order]
        first = np.ones(skey.size, bool)
        first[1:] = skey[1:] != skey[:-1]
        slot = np.empty(skey.size, np.intp)
        slot[order] = np.cumsum(first) - 1
        ukey = skey[first]
        self.slot, self.nslots = slot, ukey.size
        self.indices = (ukey % self.n).astype(np.int32)
        self.col_of = (ukey // self.n).astype(np.intp)
        self.indptr = np.zeros(self.n + 1, np.int32)
        np.cumsum(np.bincount(self.col_of, minlength=self.n), out=self.indptr[1:])
        self.rows, self.cols = rows, cols

    def __call__(self, terms, G) -> sp.csc_matrix:
        """The matrix for ``terms`` = ``[(X_1, c_1), (X_2, c_2), ...]`` and ``G``."""
        nq = self.nq
        rows, cols, data = [], [], []
        for X, c in terms:
            r, k, d = triplets(X)
            rows.append(r)
            cols.append(k)
            data.append(c * d)
        r, k, d = triplets(G)
        rows += [r + nq, k]
        cols += [k, r + nq]
        data += [d, d]
        rows, cols = np.concatenate(rows), np.concatenate(cols)
        if (self.rows is None or rows.size != self.rows.size
                or not (np.array_equal(rows, self.rows) and np.array_equal(cols, self.cols))):
            self._layout(rows, cols)
        values = np.bincount(self.slot, weights=np.concatenate(data), minlength=self.nslots)
        keep = values != 0.0
        if keep.all():
            indices, indptr = self.indices, self.indptr
        else:
            values, indices = values[keep], self.indices[keep]
            indptr = np.zeros(self.n + 1, np.int32)
            np.cumsum(np.bincount(self.col_of[keep], minlength=self.n), out=indptr[1:])
        return sp.csc_matrix((values, indices, indptr), shape=(self.n, self.n))


def identity_minus(c: float, J):
    """``I - c J``: sparse (CSC) when ``J`` is sparse, else dense."""
    n = J.shape[0]
    if sp.issparse(J):
        return sp.csc_matrix(sp.identity(n, format="csc") - c * J)
    return np.eye(n) - c * J


class GroupedDifferences:
    """Forward differences of ``fun`` on a known sparsity pattern.

    Parameters
    ----------
    sparsity : sparse matrix or array, shape (n, n)
        Structural non-zeros of ``df/dy``.

    Columns that share no row are perturbed together (Curtis, Powell and
    Reid 1974), so one Jacobian costs ``ngroups`` evaluations of ``fun``; the
    increment of column ``j`` is ``sqrt(eps) max(|y_j|, scale_j, 1e-5)``, that
    of the dense differences in :mod:`integrator_bench.integrators.newton`.
    """

    def __init__(self, sparsity):
        P = sp.csc_matrix(sparsity, dtype=float)
        P.sum_duplicates()
        P.sort_indices()
        self.n = P.shape[1]
        self.indices, self.indptr = P.indices, P.indptr
        groups = group_columns(P, order=np.arange(self.n))
        column = np.repeat(np.arange(self.n), np.diff(P.indptr))
        self.column = column
        self.groups = [(np.flatnonzero(groups == g), np.flatnonzero(groups[column] == g))
                       for g in range(int(groups.max(initial=-1)) + 1)]

    @property
    def ngroups(self) -> int:
        return len(self.groups)

    def __call__(self, fun, t, y, f0, scale):
        """``df/dy`` at ``(t, y)`` as a CSC matrix; ``f0 = fun(t, y)``."""
        delta = np.sqrt(_EPS) * np.maximum(np.maximum(np.abs(y), scale), 1e-5)
        data = np.zeros(self.indices.size)
        for cols, entries in self.groups:
            yg = np.array(y, dtype=float)
            yg[cols] += delta[cols]
            df = np.asarray(fun(t, yg), float) - f0
            data[entries] = df[self.indices[entries]] / delta[self.column[entries]]
        return sp.csc_matrix((data, self.indices, self.indptr), shape=(self.n, self.n))


def pattern(matrix) -> sp.csc_matrix:
    """The structure of ``matrix`` and the diagonal, as a canonical CSC matrix of ones
    (the diagonal, because ``I - c J`` has it whatever ``J`` holds)."""
    P = sp.csc_matrix(matrix, dtype=float, copy=True)
    P.data[:] = 1.0
    P = sp.csc_matrix(P + sp.identity(P.shape[0], format="csc"))
    P.data[:] = 1.0
    P.sort_indices()
    return P


def bandwidths(P) -> tuple[int, int]:
    """``(ml, mu)``: lower and upper bandwidth of the structure ``P``."""
    P = sp.coo_matrix(P)
    d = P.row.astype(np.int64) - P.col.astype(np.int64)
    return int(max(d.max(initial=0), 0)), int(max(-d.min(initial=0), 0))


def on_pattern(J, P) -> np.ndarray:
    """The values of ``J`` at the entries of the canonical CSC structure ``P``, in
    ``P``'s order (zeros where ``J`` has no entry).

    Raises
    ------
    ValueError
        When ``J`` has a non-zero outside ``P`` (the structure would drop it).
    """
    J = sp.csc_matrix(J)
    J.sum_duplicates()
    n = np.int64(P.shape[0])
    key_p = np.repeat(np.arange(P.shape[1], dtype=np.int64), np.diff(P.indptr)) * n + P.indices
    key_j = np.repeat(np.arange(J.shape[1], dtype=np.int64), np.diff(J.indptr)) * n + J.indices
    pos = np.searchsorted(key_p, key_j)
    pos = np.minimum(pos, key_p.size - 1)
    inside = key_p[pos] == key_j
    if np.any(J.data[~inside] != 0):
        raise ValueError("the Jacobian has non-zeros outside its declared sparsity pattern")
    values = np.zeros(P.nnz)
    values[pos[inside]] = J.data[inside]
    return values


def to_banded(J, ml: int, mu: int) -> np.ndarray:
    """``J`` in LAPACK's packed band format, ``B[mu + i - j, j] = J[i, j]``.

    Raises
    ------
    ValueError
        When ``J`` has a non-zero outside the band.
    """
    J = sp.coo_matrix(J)
    row = mu + J.row.astype(np.int64) - J.col
    inside = (row >= 0) & (row <= ml + mu)
    if np.any(J.data[~inside] != 0):
        raise ValueError(f"the Jacobian has non-zeros outside its band ({ml}, {mu})")
    B = np.zeros((ml + mu + 1, J.shape[1]))
    np.add.at(B, (row[inside], J.col[inside]), J.data[inside])
    return B
