"""What a finished run folder holds, recorded in its manifest and checked when a batch resumes.

A run writes, last, the size and SHA-256 of every file of its folder into ``manifest.json`` (``files``). A batch
counts the folder as finished only when each of those files is there with that size and content: a deleted
``episodes.csv`` or a truncated ``violations.csv`` (a disk error, a careless edit) makes the run run again, with a
warning that names the file, instead of the batch's CSVs silently losing its rows.
"""
from __future__ import annotations

import hashlib
from pathlib import Path

CHUNK_BYTES = 1 << 20  # read 1 MiB at a time while hashing


def sha256_of(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as fh:
        for chunk in iter(lambda: fh.read(CHUNK_BYTES), b""):
            digest.update(chunk)
    return digest.hexdigest()


def folder_files(folder: Path, left_out: tuple[str, ...]) -> dict[str, dict[str, int | str]]:
    """Every file of ``folder`` (its name → ``{"bytes": size, "sha256": hex digest}``) except ``left_out``."""
    return {path.name: {"bytes": path.stat().st_size, "sha256": sha256_of(path)}
            for path in sorted(folder.iterdir()) if path.is_file() and path.name not in left_out}


def damage(folder: Path, listed: object) -> str | None:
    """What is wrong with the files of ``folder`` that its manifest lists (``listed``: its ``files``), as a phrase
    naming the first damaged file; None when every one is there, whole."""
    if not isinstance(listed, dict) or not listed:
        return f"{folder / 'manifest.json'} lists no files (a run of an older sumo_rss, or a damaged manifest)"
    for name, expected in listed.items():
        path = folder / name
        if not isinstance(expected, dict) or "/" in name or name.startswith("."):
            return f"{folder / 'manifest.json'}: its entry for {name!r} is damaged"
        if not path.is_file():
            return f"{path} is missing"
        size = path.stat().st_size
        if size != expected.get("bytes"):
            return f"{path} has {size} bytes, the run wrote {expected.get('bytes')}"
        if sha256_of(path) != expected.get("sha256"):
            return f"{path} is not what the run wrote (its SHA-256 differs)"
    return None
