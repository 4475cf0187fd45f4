"""Results of a run: logs on disk, metrics, the paper's figures, diagrams and 3D replay."""

from drake_coop.results.block_diagram import paper_block_diagram
from drake_coop.results.export import write_diagram, write_subsystem_diagram
from drake_coop.results.figures import fig_references, plot_figures, replot
from drake_coop.results.io import atomic_path, atomic_write_bytes, atomic_write_text
from drake_coop.results.logs import load_logs, save_logs
from drake_coop.results.graph import connected_graphviz
from drake_coop.results.metrics import compute_metrics, write_metrics

#: The diagram export helpers work on any Diagram (a user's own too): ``write_diagram``,
#: ``write_subsystem_diagram`` (DOT + SVG), ``connected_graphviz``, ``paper_block_diagram``.
__all__ = ["atomic_path", "atomic_write_bytes", "atomic_write_text", "compute_metrics",
           "connected_graphviz", "fig_references", "load_logs", "paper_block_diagram",
           "plot_figures", "replot", "save_logs", "write_diagram", "write_metrics",
           "write_subsystem_diagram"]
