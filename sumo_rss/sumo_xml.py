"""Reading SUMO's XML outputs element by element (constant memory), checking that a file is the output asked for;
gzipped outputs (``*.gz``, as SUMO writes them when asked for such a name) are read as they are."""
from __future__ import annotations

import gzip
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from pathlib import Path
from typing import IO

MALFORMED = (ET.ParseError, EOFError, gzip.BadGzipFile)  # what reading a damaged (or cut) output raises


def open_output(path: Path) -> IO[bytes]:
    """``path`` opened for reading, through gzip for a ``.gz`` name."""
    return gzip.open(path, "rb") if Path(path).suffix == ".gz" else open(path, "rb")


def bytes_consumed(source: IO[bytes]) -> int:
    """How far reading ``source`` (from :func:`open_output`) has got into its file [bytes on disk: a gzipped
    file's compressed bytes], for progress over the file's size."""
    return (source.fileobj if isinstance(source, gzip.GzipFile) else source).tell()


def output_elements(path: Path, root_tag: str, tag: str) -> Iterator[ET.Element]:
    """The ``tag`` elements of the SUMO output ``path``, whose root must be ``root_tag``; ValueError naming the
    root found otherwise, one of MALFORMED for a damaged file."""
    with open_output(path) as source:
        context = ET.iterparse(source, events=("start", "end"))
        try:
            _, root = next(context)
        except StopIteration:
            raise ValueError("an empty file") from None
        if root.tag != root_tag:
            raise ValueError(f"root element <{root.tag}>, expected <{root_tag}>")
        for event, elem in context:
            if event == "end" and elem.tag == tag:
                yield elem
                root.clear()  # read: dropped, so memory stays constant over a long output
