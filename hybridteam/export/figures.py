"""Writing figures: the file formats views take, and saving without partial files.

Shared by every matplotlib view (timeline, trajectories, study plots), so a figure is
written the same way whatever draws it: by extension, atomically, reproducibly.
"""

from __future__ import annotations

import io
import os
from pathlib import Path

from matplotlib import rc_context
from matplotlib.figure import Figure

from hybridteam.trace import write_atomic

FIGURE_FORMATS = {".png": "png", ".svg": "svg", ".pdf": "pdf"}
DATA_FORMATS = {".csv": "csv", ".json": "json"}


def figure_format(path: str | os.PathLike, formats: dict[str, str] = FIGURE_FORMATS) -> str:
    suffix = Path(path).suffix.lower()
    if suffix not in formats:
        raise ValueError(
            f"{path}: unsupported format {suffix or '(none)'}; use one of {', '.join(formats)}"
        )
    return formats[suffix]


def save_figure(fig: Figure, path: str | os.PathLike, tight: bool = True) -> Path:
    """Save as PNG, SVG or PDF (by extension) without leaving a partial file; text stays
    text in SVG (searchable, and the names can be checked), PDF is vector for papers, and no
    date is stamped into either (the same figure gives the same bytes). ``tight`` crops to
    what is drawn; off, the file has the figure's own size (a size the user asked for)."""
    path = Path(path)
    fmt = figure_format(path)
    buf = io.BytesIO()
    metadata = {
        "svg": {"Date": None},
        "pdf": {"CreationDate": None, "ModDate": None, "Producer": None},
    }.get(fmt)
    with rc_context({"svg.fonttype": "none", "svg.hashsalt": "hybridteam"}):
        fig.savefig(
            buf, format=fmt, bbox_inches="tight" if tight else None, dpi=fig.dpi, metadata=metadata
        )
    return write_atomic(path, buf.getvalue())
