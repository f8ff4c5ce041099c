"""EPSILON motion layer: spatio-temporal semantic corridor and piecewise Bézier QP on osqp (epsilon.md §6)."""
