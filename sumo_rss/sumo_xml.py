"""Reading SUMO's XML outputs element by element (constant memory), checking that a file is the output asked for;
gzipped outputs (``*.gz``, as SUMO writes them when asked for such a name) are read as they are."""
from __future__ import annotations

import gzip
import warnings
import xml.etree.ElementTree as ET
import zlib
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO
from xml.parsers import expat

# What reading a damaged (or cut) output raises; zlib.error: a gzipped file whose compressed stream is damaged.
MALFORMED = (ET.ParseError, EOFError, gzip.BadGzipFile, zlib.error)
# What expat reports when the input ends before the document does (it asks for more bytes than the file has).
_CUT_CODES = frozenset(expat.errors.codes[message] for message in (
    expat.errors.XML_ERROR_NO_ELEMENTS, expat.errors.XML_ERROR_UNCLOSED_TOKEN, expat.errors.XML_ERROR_PARTIAL_CHAR,
    expat.errors.XML_ERROR_UNCLOSED_CDATA_SECTION))


def open_output(path: Path) -> IO[bytes]:
    """``path`` opened for reading, through gzip for a ``.gz`` name."""
    return gzip.open(path, "rb") if Path(path).suffix == ".gz" else open(path, "rb")


def root_tag(path: Path) -> str:
    """The tag of the root element of the XML file ``path`` (gzipped for a ``.gz`` name), read without the rest;
    one of MALFORMED where the file is not XML up to there."""
    with open_output(path) as source:
        _, root = next(ET.iterparse(source, events=("start",)))
        return root.tag


def ends_with_end_tag(path: Path, root_tag: str) -> bool:
    """Whether the (plain) XML file ``path`` ends with its root's end tag ``</root_tag>``, as a SUMO output that was
    closed (SUMO writes it last; a file cut by a full disk or a file-size limit does not have it)."""
    with open(path, "rb") as fh:
        fh.seek(0, 2)
        fh.seek(max(0, fh.tell() - len(root_tag) - 64))
        return fh.read().rstrip().endswith(f"</{root_tag}>".encode())


def bytes_consumed(source: IO[bytes]) -> int:
    """How far reading ``source`` (from :func:`open_output`) has got into its file [bytes on disk: a gzipped
    file's compressed bytes], for progress over the file's size."""
    return (source.fileobj if isinstance(source, gzip.GzipFile) else source).tell()


def ends_cut(error: BaseException, source: IO[bytes]) -> bool:
    """Whether reading ``source`` failed with ``error`` (one of MALFORMED) only because the file ends before its
    document does, as it does when SUMO is killed while writing it: a gzip stream that ends early, or expat asking
    for more once every byte has been read. Damage inside the file is not a cut."""
    if isinstance(error, EOFError):
        return True
    if not (isinstance(error, ET.ParseError) and error.code in _CUT_CODES):
        return False
    try:
        return source.read(1) == b""
    except MALFORMED:
        return False


def output_elements(path: Path, root_tag: str, tag: str,
                    on_cut: Callable[[int], None] | None = None) -> Iterator[ET.Element]:
    """The ``tag`` elements of the SUMO output ``path``, whose root must be ``root_tag``; ValueError naming the
    root found otherwise, one of MALFORMED for a damaged file. A cut file (:func:`ends_cut`) gives its complete
    elements, with a warning; ``on_cut(number of complete elements)`` is called then too."""
    count, root = 0, None
    with open_output(path) as source:
        context = ET.iterparse(source, events=("start", "end"))
        try:
            try:
                _, root = next(context)
            except StopIteration:
                raise ValueError("an empty file") from None
            if root.tag != root_tag:
                raise ValueError(f"root element <{root.tag}>, expected <{root_tag}>")
            for event, elem in context:
                if event == "end" and elem.tag == tag:
                    count += 1
                    yield elem
                    root.clear()  # read: dropped, so memory stays constant over a long output
        except MALFORMED as exc:
            if not ends_cut(exc, source):
                raise
            # Before the root: a run killed before SUMO wrote more than the header comment.
            where, read = (f"before its root element <{root_tag}>", f"no <{tag}> records") if root is None else \
                (f"before its end tag </{root_tag}>", f"read its {count} complete <{tag}> records")
            warnings.warn(f"{path}: the file ends {where} (cut off, as when SUMO is killed while writing it): {read}",
                          stacklevel=3)
            if on_cut is not None:
                on_cut(count)
