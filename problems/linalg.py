"""Linear algebra the mechanical formulations share: LAPACK's dense solve without
numpy's wrapping, SuperLU with LAPACK's error, the augmented (KKT) matrix and the
union of sparse patterns."""

from __future__ import annotations

import numpy as np
from scipy.linalg.lapack import dgesv as _gesv, dpotrs as _potrs, dpstrf as _pstrf
import scipy.sparse as sp
import scipy.sparse.linalg as spla


def kkt(M, G):
    """The augmented matrix ``[[M, G^T], [G, 0]]`` of sparse ``M`` and ``G``, in CSC."""
    return sp.bmat([[M, G.T], [G, None]], format="csc")


def solve(A, b, overwrite: bool = False):
    """``A^-1 b`` for a dense ``A`` by LAPACK's ``gesv``, without numpy's generic
    wrapping (a few microseconds a call on a small system); ``LinAlgError``
    when ``A`` is singular, as ``numpy.linalg.solve`` raises. ``overwrite``:
    ``A`` and ``b`` may be factored and solved in place (no copy when they are
    Fortran-contiguous)."""
    _, _, x, info = _gesv(A, b, overwrite_a=overwrite, overwrite_b=overwrite)
    if info > 0:
        raise np.linalg.LinAlgError("Singular matrix")
    return x


def splu(A):
    """SuperLU's factors of the sparse ``A``; ``LinAlgError`` (as LAPACK's dense
    solvers raise) where SuperLU finds it exactly singular."""
    try:
        return spla.splu(A)
    except RuntimeError as exc:   # SuperLU: "Factor is exactly singular"
        raise np.linalg.LinAlgError(str(exc)) from None


def ones_pattern(*blocks):
    """Union of the stored entries of sparse matrices of one shape, explicit zeros
    included, as ones (CSR): every block's stored values are set to one before
    the sum, so that nothing cancels and no stored zero is dropped."""
    total = None
    for b in blocks:
        b = sp.csr_matrix(b, dtype=float, copy=True)
        b.data[:] = 1.0
        total = b if total is None else total + b
    return total


def solve_dropping_dependent(A, b, rank: int, rcond: float):
    """A solution of ``A x = b`` for a symmetric positive semi-definite ``A`` of
    rank at most ``rank`` (``G M^-1 G^T`` of a mechanism with redundant
    constraints), by Cholesky factorization with complete pivoting (LAPACK's
    ``dpstrf``; Higham, Accuracy and Stability of Numerical Algorithms, 2nd ed.
    (2002), sect. 10.3): the pivots choose the ``rank`` most independent rows (fewer
    where a pivot falls below ``rcond`` times the largest diagonal entry), the
    others, the dependent constraints, are dropped (their ``x`` is zero). Exact
    when ``b`` lies in the range of ``A``; about ten times cheaper than an SVD
    least-squares solve of a 24 x 24 system."""
    c, piv, found, info = _pstrf(A, lower=0, tol=rcond * float(np.max(np.diag(A), initial=0)))
    if info < 0:
        raise np.linalg.LinAlgError(f"dpstrf: illegal argument {-info}")
    r = min(int(found), rank)
    keep = piv[:r] - 1
    x = np.zeros(A.shape[0])
    x[keep] = _potrs(c[:r, :r], b[keep], lower=0)[0]   # the factor's upper triangle
    return x
