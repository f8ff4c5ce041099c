"""EPSILON planner port (no libsumo): the EUDM behaviour layer drives the ego (``controller = "epsilon"``), the
MPDM baseline is ``controller = "mpdm"``; see docs/planner.md and ../shared/design/epsilon.md. The motion layer
(SSC) and the learned intention estimator are not part of this version yet."""
