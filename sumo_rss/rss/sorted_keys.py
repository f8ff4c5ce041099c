"""Look-ups of keys (pair keys, episode serials, vehicle uids; also strings, e.g. edge ids) in sorted key arrays,
vectorised."""
from __future__ import annotations

import numpy as np


def find_sorted(sorted_keys: np.ndarray, query: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(found, position) of each ``query`` key in ``sorted_keys``; positions are valid indices where found."""
    if len(sorted_keys) == 0:
        return np.zeros(len(query), dtype=bool), np.zeros(len(query), dtype=int)
    pos = np.clip(np.searchsorted(sorted_keys, query), 0, len(sorted_keys) - 1)
    return sorted_keys[pos] == query, pos
