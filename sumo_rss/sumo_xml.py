"""Reading SUMO's XML outputs element by element (constant memory), checking that a file is the output asked for."""
from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Iterator
from pathlib import Path


def output_elements(path: Path, root_tag: str, tag: str) -> Iterator[ET.Element]:
    """The ``tag`` elements of the SUMO output ``path``, whose root must be ``root_tag``; ValueError naming the
    root found otherwise, ET.ParseError for malformed XML."""
    context = ET.iterparse(path, events=("start", "end"))
    try:
        _, root = next(context)
    except StopIteration:
        raise ValueError("an empty file") from None
    if root.tag != root_tag:
        raise ValueError(f"root element <{root.tag}>, expected <{root_tag}>")
    for event, elem in context:
        if event == "end" and elem.tag == tag:
            yield elem
