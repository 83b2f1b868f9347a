"""Checks on the figures the code saves: titles, axis labels, units."""

from __future__ import annotations

from pathlib import Path


def figure_labels(fig) -> dict:
    """{"title": suptitle or the axes' titles, "axes": [(xlabel, ylabel)] of every visible axes with data}."""
    axes = [ax for ax in fig.axes if ax.axison and (ax.lines or ax.patches or ax.collections)]
    title = fig._suptitle.get_text() if fig._suptitle is not None else ""
    def xlabel(ax):  # stacked panels sharing x label it once, on the bottom one
        return next((a.get_xlabel() for a in ax.get_shared_x_axes().get_siblings(ax) if a.get_xlabel()), "")

    return {"title": title or " / ".join(ax.get_title() for ax in axes if ax.get_title()),
            "axes": [(xlabel(ax), ax.get_ylabel()) for ax in axes]}


def spy_on_savefig(original, seen: dict):
    """A ``Figure.savefig`` that records ``seen[file name] = figure_labels(fig)`` before saving."""
    def spy(self, fname, *args, **kwargs):
        seen[Path(str(fname)).name] = figure_labels(self)
        return original(self, fname, *args, **kwargs)

    return spy


def assert_labelled(figures: dict) -> None:
    """Every figure has a title; every axes with data labels both axes, and one of them carries a unit [..]."""
    assert figures, "no figure was saved"
    for name, f in figures.items():
        assert f["title"].strip(), f"{name}: no title"
        for xlabel, ylabel in f["axes"]:
            assert xlabel.strip() and ylabel.strip(), f"{name}: unlabelled axis ({xlabel!r}, {ylabel!r})"
            assert "[" in xlabel + ylabel, f"{name}: no unit on ({xlabel!r}, {ylabel!r})"
