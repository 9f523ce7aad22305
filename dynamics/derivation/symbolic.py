"""The former home of the symbolic helpers, kept for code that imports them from here: they
live in :mod:`nhgait.dynamics.algebra` (the layer below the derivation and the numerics), one
idea per module — :mod:`~nhgait.dynamics.algebra.trig` (the trig normal form),
:mod:`~nhgait.dynamics.algebra.ring` (fractions of one polynomial ring),
:mod:`~nhgait.dynamics.algebra.fraction_field` (``FracField``),
:mod:`~nhgait.dynamics.algebra.matrix_ops` (``MatrixOps``) and
:mod:`~nhgait.dynamics.algebra.matrices` (null spaces, plain determinants, pivots)."""
from __future__ import annotations

from ..algebra.fraction_field import FracField, as_sympy  # noqa: F401 - re-exported
from ..algebra.matrices import (  # noqa: F401
                                LARGE_MATRIX_NODES,
                                is_large,
                                null_basis_adjugate,
                                numeric_pivots,
                                plain_adjugate,
                                plain_det,
                                strip_factors,
)
from ..algebra.matrix_ops import MatrixOps  # noqa: F401
from ..algebra.ring import NotRational, WorkBudgetExceeded  # noqa: F401
from ..algebra.trig import TIDY_NODES, has_trig, independent_arguments, tidy, tree_size, trig_normal  # noqa: F401
