"""EPSILON planner port (no libsumo): the EUDM behaviour layer (``behavior/``), the SSC motion layer (``motion/``) and
the learned intention estimator (``intention/``) drive the ego (``controller = "epsilon"``); the MPDM baseline is
``controller = "mpdm"``. See docs/planner.md, docs/motion.md, docs/intention.md and ../shared/design/epsilon.md."""
