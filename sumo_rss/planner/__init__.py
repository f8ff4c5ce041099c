"""EPSILON planner port (no libsumo): behaviour layer (EUDM) first; see ../shared/design/epsilon.md.

Work in progress: the building blocks here are tested, the planner is not wired to scenarios yet
(``controller = "epsilon"`` is refused by ``sumo-rss run``).
"""
