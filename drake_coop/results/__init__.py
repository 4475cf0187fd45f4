"""Results of a run: logs on disk, metrics, the paper's figures, diagrams and 3D replay."""

from drake_coop.results.figures import fig_references, plot_figures, replot
from drake_coop.results.io import atomic_path, atomic_write_bytes, atomic_write_text
from drake_coop.results.logs import load_logs, save_logs
from drake_coop.results.metrics import compute_metrics, write_metrics

__all__ = ["atomic_path", "atomic_write_bytes", "atomic_write_text", "compute_metrics",
           "fig_references", "load_logs", "plot_figures", "replot", "save_logs",
           "write_metrics"]
