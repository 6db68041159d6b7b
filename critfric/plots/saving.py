"""Figures written safely: every target checked before anything is drawn to disk (no symbolic
link, no directory, a writable directory), then all written aside and renamed into place, so
that a failure leaves no half-written image and never writes through a link."""

from __future__ import annotations

from pathlib import Path

from matplotlib.figure import Figure

from ..errors import CaseError
from ..files.safety import check_output, staged

FORMATS = ("png", "pdf", "svg")


def check_figure_paths(paths, *, inputs=(), key: str | None = None) -> list[Path]:
    """Refuse any of ``paths`` that is a link, a directory, an input or in a directory that
    cannot be written (:class:`~critfric.errors.CaseError` naming it); an existing regular
    file is overwritten; the suffix must be one of :data:`FORMATS`."""
    out = []
    for p in map(Path, paths):
        if p.suffix.lstrip(".").lower() not in FORMATS:
            raise CaseError(f"got suffix {p.suffix or 'none'!r}; allowed: a figure file "
                            "ending in " + ", ".join("." + f for f in FORMATS),
                            file=str(p), key=key)
        out.append(check_output(p, force=True, inputs=inputs, key=key))
    return out


def save_figures(items: list[tuple[Figure, Path]], *, inputs=(), key: str | None = None,
                 **savefig) -> list[Path]:
    """Write each ``(figure, path)`` of ``items`` (all in one directory; the format is the
    suffix's) with ``savefig`` options: checked first, written to a private directory beside
    the targets, then renamed over them. A full disk or an I/O error is a
    :class:`~critfric.errors.WriteError` and leaves no new or partial file."""
    if not items:
        return []
    targets = check_figure_paths([p for _, p in items], inputs=inputs, key=key)
    by_folder: dict[Path, list[int]] = {}
    for k, target in enumerate(targets):
        by_folder.setdefault(target.parent, []).append(k)
    for indices in by_folder.values():  # a rename works within one file system: per folder
        with staged([targets[k] for k in indices], key=key) as aside:
            for k, tmp in zip(indices, aside):
                items[k][0].savefig(tmp, format=targets[k].suffix.lstrip(".").lower(),
                                    **savefig)
    return targets
