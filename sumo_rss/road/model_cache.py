"""A disk cache of the road models built from a network file, so that a city network is read and built once.

An entry is keyed by the SHA-256 of the network file's bytes (a changed file is a new key) and by what it holds
(``kind``: the road network, the junction model, the signal programs, the topology index). Its header names the
format, the kind, the network's hash, a fingerprint of the code that builds the models and the payload's own hash;
an entry whose header does not match, or whose payload is damaged, is rebuilt and overwritten, never used. Entries
are written atomically (a temporary file renamed into place), so concurrent runs of one network never read half an
entry.

Where: ``$SUMO_RSS_CACHE_DIR`` if set (``off`` turns the cache off), else ``$XDG_CACHE_HOME/sumo_rss``, else
``~/.cache/sumo_rss``. A directory that cannot be written to leaves every run building the models itself (with one
warning).
"""
from __future__ import annotations

import hashlib
import json
import os
import pickle
import sys
import tempfile
import warnings
from collections.abc import Callable
from functools import lru_cache
from pathlib import Path
from typing import TypeVar

import numpy as np

CACHE_ENV = "SUMO_RSS_CACHE_DIR"
CACHE_OFF = "off"
FORMAT = 1  # of the entry file itself (the code that builds the models is fingerprinted separately)
MAGIC = b"sumo_rss road model cache\n"
# The modules whose code decides what a cached model holds: an entry built by other code is not used.
_BUILDERS = ("crossings", "frenet", "junctions", "link_pairs", "model_cache", "net_check", "net_file", "network", "reach",
             "strip_overlap", "topology", "two_way")
T = TypeVar("T")
_kept: dict[str, tuple[str, object]] = {}  # kind → (network's digest, model) of the last kept model
_warned_unwritable = False


def cache_dir() -> Path | None:
    """The cache directory, None when the cache is off."""
    chosen = os.environ.get(CACHE_ENV)
    if chosen is not None:
        return None if chosen.strip().lower() in (CACHE_OFF, "") else Path(chosen).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "sumo_rss"


def cached(net_file: Path, kind: str, build: Callable[[], T], keep: bool = False) -> T:
    """The model ``kind`` of ``net_file``: from the cache when an intact entry of this file's content, built by
    this code, is there; else ``build()``, stored for the next run. ``keep``: the model is never changed by its
    users, so the process keeps the last one of its kind and hands out that one while the file is unchanged."""
    digest = net_digest(net_file)
    kept = _kept.get(kind)
    if keep and kept is not None and kept[0] == digest:
        return kept[1]
    directory = cache_dir()
    header = {"format": FORMAT, "kind": kind, "net_sha256": digest, "code": code_fingerprint()}
    entry = directory / f"{kind}-{digest[:40]}.pkl" if directory is not None else None
    model = _load(entry, header) if entry is not None else None
    if model is None:
        model = build()
        if entry is not None:
            _store(entry, header, model)
    if keep:
        _kept[kind] = (digest, model)
    return model


def net_digest(net_file: Path) -> str:
    """SHA-256 (hex) of the file's bytes (worked out again only when its size or modification time changed)."""
    status = Path(net_file).stat()
    return _digest(Path(net_file).resolve(), status.st_size, status.st_mtime_ns)


@lru_cache(maxsize=32)
def _digest(path: Path, size: int, modified_ns: int) -> str:
    sha = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            sha.update(block)
    return sha.hexdigest()


@lru_cache(maxsize=1)
def code_fingerprint() -> str:
    """SHA-256 of the source of the modules that build the cached models, and of the Python and numpy versions
    that pickle them."""
    sha = hashlib.sha256(f"{sys.version_info[:2]} numpy {np.__version__}".encode())
    for name in _BUILDERS:
        sha.update((Path(__file__).parent / f"{name}.py").read_bytes())
    return sha.hexdigest()


def _load(entry: Path, header: dict) -> object | None:
    """The model in ``entry`` if its header is ``header`` and its payload intact, else None."""
    try:
        data = entry.read_bytes()
    except OSError:
        return None
    try:
        head_end = data.index(b"\n", len(MAGIC))
        found = json.loads(data[len(MAGIC):head_end])
        payload = memoryview(data)[head_end + 1:]  # not a copy: a city's entry is a few hundred MB
        if not data.startswith(MAGIC) or found.pop("payload_sha256") != hashlib.sha256(payload).hexdigest() or \
                found != header:
            return None
        return pickle.loads(payload)
    except Exception:  # noqa: BLE001 (whatever a damaged entry raises, it is rebuilt)
        return None


def _store(entry: Path, header: dict, model: object) -> None:
    """Write ``model`` to ``entry`` atomically; a directory that cannot be written is warned about once."""
    global _warned_unwritable
    payload = pickle.dumps(model, protocol=pickle.HIGHEST_PROTOCOL)
    head = json.dumps({**header, "payload_sha256": hashlib.sha256(payload).hexdigest()}, sort_keys=True).encode()
    try:
        entry.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=entry.parent, prefix=f".{entry.name}.", delete=False) as tmp:
            tmp.write(MAGIC + head + b"\n")
            tmp.write(payload)
        os.replace(tmp.name, entry)
    except OSError as exc:
        try:
            os.unlink(tmp.name)
        except (OSError, NameError):
            pass
        if not _warned_unwritable:
            _warned_unwritable = True
            warnings.warn(f"{entry.parent}: cannot write the road model cache ({exc}); networks are built on every "
                          f"run (set {CACHE_ENV} to a writable directory, or to '{CACHE_OFF}')", stacklevel=3)
