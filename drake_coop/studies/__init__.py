"""Parameter studies and Monte Carlo: study files, expansion, engines (local pool, Ray),
results store, figures and the ``drake-coop study`` command."""

from drake_coop.studies.expand import Case, expand
from drake_coop.studies.spec import Study, StudyError, load_study

__all__ = ["Case", "Study", "StudyError", "expand", "load_study"]
