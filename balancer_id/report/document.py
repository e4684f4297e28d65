"""Reports as one file: self-contained HTML or a PDF (matplotlib only, no other dependency).

The writer. A report is a title and a list of
:class:`~balancer_id.report.blocks.Section` (the document model, :mod:`.blocks`);
``fit`` builds its sections with :func:`~balancer_id.report.fit_sections.fit_sections`,
``compare``, ``diagnose`` and ``improve`` add theirs (:mod:`.sections`) through
``extra_sections``. :func:`write_report` is the one entry point that writes a file: it
appends the provenance (files analysed with their SHA-256, software versions, date),
renders with :mod:`.html` or :mod:`.pdf`, writes the file whole or not at all and never
overwrites an input log. Nothing here fits or diagnoses: the sections render results.

The format follows the suffix: ``.html`` (or ``.htm``) or ``.pdf``.
"""

from __future__ import annotations

import hashlib
import os
import sys
from collections.abc import Iterable, Sequence
from datetime import datetime
from pathlib import Path
from typing import TYPE_CHECKING

from balancer_id.errors import UsageError
from balancer_id.files import atomic_write
from balancer_id.numbers import format_estimate, format_interval, format_number
from balancer_id.report.blocks import (
    Block,
    Cell,
    Paragraph,
    Plot,
    Preformatted,
    Section,
    Subheading,
    Table,
)
from balancer_id.report.fit_sections import fit_sections, reproduce_section
from balancer_id.report.html import _render_html
from balancer_id.report.pdf import render_pdf

if TYPE_CHECKING:

    from balancer_id.identify.result import FitResult

#: Report formats by suffix.
FORMATS = {".html": "html", ".htm": "html", ".pdf": "pdf"}

__all__ = [
    "FORMATS",
    "Cell",
    "Paragraph",
    "Plot",
    "Preformatted",
    "Section",
    "Subheading",
    "Table",
    "check_report_path",
    "fit_sections",
    "format_estimate",
    "format_interval",
    "format_number",
    "write_fit_report",
    "write_report",
]


# --------------------------------------------------------------------------------------
# the fit report
# --------------------------------------------------------------------------------------
def write_fit_report(
    result: FitResult,
    path: str | Path,
    *,
    extra_sections: list[Section] | None = None,
    lead_sections: list[Section] | None = None,
    warnings: Sequence[object] | None = None,
) -> Path:
    """Write the report of a fit as FILE.html or FILE.pdf (chosen by the suffix).

    Parameters
    ----------
    result : FitResult
        What :func:`balancer_id.identify.fit` returned.
    path : str or Path
        The report file; ``.html``/``.htm`` or ``.pdf``.
    extra_sections : list of Section, optional
        Sections of other commands (compare, diagnose, improve), placed after the fit's.
    lead_sections : list of Section, optional
        Sections placed first (the finding of a diagnosis).
    warnings : sequence of str or Note, optional
        The fit's warnings as a diagnosis reads them; None: the fit's own.

    Returns
    -------
    Path
        ``path``, written whole.

    Raises
    ------
    UsageError
        Another suffix, a missing directory, or ``path`` is one of the input logs.
    """
    check_report_path(path, result.sources)
    n_trials = len(result.match.data.trials)
    n_logs = len(result.sources)
    sections = [
        *(lead_sections or []),
        *fit_sections(result, warnings),
        *(extra_sections or []),
        reproduce_section(result),
    ]
    return write_report(
        f"Balancer identification: {result.model}",
        sections,
        path,
        inputs=result.sources,
        subtitle=f"{n_trials} step trial{'s' * (n_trials != 1)} from "
        f"{n_logs} log{'s' * (n_logs != 1)}",
    )


# --------------------------------------------------------------------------------------
# the general writer
# --------------------------------------------------------------------------------------
def check_report_path(path: str | Path, inputs: Iterable[str | Path] = ()) -> str:
    """The report format of ``path``, refusing what must not be written.

    Parameters
    ----------
    path : str or Path
        The report file.
    inputs : iterable of path
        Input logs, which a report must never replace.

    Returns
    -------
    str
        ``"html"`` or ``"pdf"``.

    Raises
    ------
    UsageError
        Unknown suffix, missing directory, a directory, or one of the inputs.
    """
    path = Path(path)
    fmt = FORMATS.get(path.suffix.lower())
    if fmt is None:
        raise UsageError(
            f"report file '{path}' must end in .html or .pdf (the suffix chooses the format)"
        )
    if path.is_dir():
        raise UsageError(f"report file '{path}' is a directory; give a file name")
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise UsageError(f"cannot write report '{path}': directory '{parent}' does not exist")
    target = path.resolve()
    for src in inputs:
        s = Path(src)
        same = s.resolve() == target
        if not same and s.exists() and path.exists():
            try:
                same = os.path.samefile(s, path)
            except OSError:
                same = False
        if same:
            raise UsageError(
                f"report file '{path}' is the input log '{src}'; refusing to overwrite it, "
                "choose another name"
            )
    return fmt


def write_report(
    title: str,
    sections: Sequence[Section],
    path: str | Path,
    *,
    inputs: Sequence[str | Path] = (),
    subtitle: str = "",
) -> Path:
    """Write a report of ``sections`` as FILE.html or FILE.pdf (chosen by the suffix).

    A last section lists the files analysed (size, modification time, SHA-256) and the
    software (balancer-id and library versions, Python, date). The file is written
    whole or not at all (temporary file, then ``os.replace``).

    Parameters
    ----------
    title : str
        The report's title.
    sections : sequence of Section
        The content, in order.
    path : str or Path
        ``.html``/``.htm`` (one self-contained file: inline CSS, figures as base64 PNG)
        or ``.pdf`` (a title page with the first section, then the rest; figures as
        vector pages).
    inputs : sequence of path
        The logs analysed: listed, and never overwritten.
    subtitle : str
        A line under the title.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    UsageError
        Unknown suffix, missing directory, or ``path`` is one of ``inputs``.
    """
    fmt = check_report_path(path, inputs)
    meta = _software()
    all_sections = [*sections, _provenance_section(inputs, meta)]
    if fmt == "html":
        text = _render_html(title, subtitle, all_sections, meta)
        data = text.encode("utf-8", "backslashreplace")  # a non-UTF-8 file name
        return atomic_write(path, lambda fh: fh.write(data))
    return atomic_write(path, lambda fh: render_pdf(fh, title, subtitle, all_sections, meta))


def _software() -> dict[str, str]:
    from importlib import metadata

    import balancer_id

    out = {"balancer-id": balancer_id.__version__}
    for pkg in ("numpy", "scipy", "lmfit", "matplotlib", "numba", "pandas"):
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            out[pkg] = "not installed"
    out["python"] = sys.version.split()[0]
    out["date"] = datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z").strip()
    return out


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _provenance_section(inputs: Sequence[str | Path], meta: dict[str, str]) -> Section:
    rows: list[list[str | Cell]] = []
    for src in inputs:
        p = Path(src)
        if p.is_file():
            st = p.stat()
            when = datetime.fromtimestamp(st.st_mtime).astimezone().strftime("%Y-%m-%d %H:%M")
            rows.append([str(src), f"{st.st_size:,} B", when, _sha256(p)])
        else:
            rows.append([str(src), "-", "-", "not found when the report was written"])
    blocks: list[Block] = []
    if rows:
        blocks.append(Table(["file", "size", "modified", "SHA-256"], rows, "Files analysed."))
    else:
        blocks.append(Paragraph("No input file was named (data given in memory)."))
    blocks.append(
        Table(
            ["software", "version"],
            [[k, v] for k, v in meta.items() if k != "date"],
            f"Written {meta['date']} on {sys.platform}.",
        )
    )
    return Section("Files and software", blocks=blocks)


# --------------------------------------------------------------------------------------
# HTML
# --------------------------------------------------------------------------------------
