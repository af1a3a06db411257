"""Reading back the data block of a page written by heatcurv.view (shared by the view tests)."""

import base64
import json
import re

import numpy as np

DATA_BLOCK = re.compile(r'<script type="application/json" id="heatcurv-data">(.*?)</script>', re.S)


def page_block(path) -> dict:
    """The JSON data block of a page."""
    text = open(path, encoding="utf-8").read()
    blocks = DATA_BLOCK.findall(text)
    assert len(blocks) == 1
    return json.loads(blocks[0])


def floats(packed) -> np.ndarray:
    """A packed float array: base64 float32 little endian times 2**exponent, as float64."""
    stored = np.frombuffer(base64.b64decode(packed["data"]), dtype="<f4").astype(np.float64)
    return np.ldexp(stored, packed["exponent"])


def positions(block) -> np.ndarray:
    """The embedded points, (count, 3), in the input's coordinates."""
    return floats(block["positions"]).reshape(-1, 3) + np.asarray(block["centre"])


def field(block, name) -> np.ndarray:
    """The embedded values of field ``name`` (coordinates from the points)."""
    entry = next(e for e in block["fields"] if e["name"] == name)
    if "axis" in entry:
        return positions(block)[:, entry["axis"]]
    return floats(entry["values"])


def byte_array(text, dtype) -> np.ndarray:
    return np.frombuffer(base64.b64decode(text), dtype=dtype)
