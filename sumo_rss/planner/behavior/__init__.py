"""EUDM behaviour layer: DCP-tree, controllers, forward simulation, evaluation (epsilon.md §2-§4)."""
