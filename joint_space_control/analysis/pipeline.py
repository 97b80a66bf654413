"""A recorded bag → ``metrics.json``, figures and ``report.md`` in one directory.

This is the one pipeline behind ``jsc analyze``, the experiment runner (each run's
``report/``) and ``jsc bench``'s analysis timing, so the three cannot drift apart. It prints
nothing: progress goes to an optional ``progress(done, total)`` callback (None: quiet), and
the caller decides what to tell the user.

Reading and writing fail differently on purpose: :class:`~joint_space_control.analysis.bag.
BagError` means the bag cannot be analysed (nothing is written), :class:`ResultsWriteError`
that the analysis worked but its results cannot be written (``jsc analyze`` exits 2 and 1).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from joint_space_control.analysis.bag import Progress
from joint_space_control.analysis.figures import controller_figures, file_prefix
from joint_space_control.analysis.report import write_metrics, write_report
from joint_space_control.analysis.run_metrics import BagAnalysis, analyze_bag


class ResultsWriteError(OSError):
    """The bag was analysed, but the results cannot be written to the output directory."""


@dataclass(frozen=True)
class AnalysisResult:
    """What :func:`analyze_bag_to` measured and the files it wrote."""

    analysis: BagAnalysis
    out_dir: Path
    metrics_path: Path
    report_path: Path
    figures: dict[str, dict[str, Path]]
    """Per controller node: figure name → PNG file."""

    @property
    def metrics(self) -> dict:
        """The JSON-ready document written to ``metrics.json``."""
        return self.analysis.metrics


def analyze_bag_to(
    out_dir: Path, bag: str | Path, progress: Progress | None = None, figures: bool = True
) -> AnalysisResult:
    """Analyse the bag at ``bag`` and write its results into ``out_dir`` (created).

    Figures of a bag with several controllers are prefixed with the node's name so that
    they do not overwrite each other; a single controller's have no prefix.

    Raises:
        BagError: the bag cannot be read or holds no controller to analyse.
        ResultsWriteError: ``out_dir`` or a file in it cannot be written.
    """
    analysis = analyze_bag(bag, progress)
    try:
        return write_analysis(analysis, out_dir, figures)
    except OSError as err:
        raise ResultsWriteError(f"cannot write the results to {out_dir}: {err}") from err


def write_analysis(analysis: BagAnalysis, out_dir: Path, figures: bool = True) -> AnalysisResult:
    """Figures (unless ``figures`` is False: most of the time of a short run's analysis,
    which a tuning trial does not need), ``metrics.json`` and ``report.md`` of ``analysis``
    into ``out_dir``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    several = len(analysis.controllers) > 1
    drawn = {
        c.metrics["node"]: controller_figures(
            c.state, c.metrics, out_dir, file_prefix(c.metrics["node"]) if several else ""
        )
        if figures
        else {}
        for c in analysis.controllers
    }
    metrics_path = write_metrics(analysis.metrics, out_dir / "metrics.json")
    report_path = write_report(analysis.metrics, drawn, out_dir)
    return AnalysisResult(analysis, out_dir, metrics_path, report_path, drawn)
