"""Importers: other tools' and datasets' files to Tactile Studio sessions.

Every importer is a long job (``progress``, ``cancel``); sessions it finished before a
cancel stay on disk, the one being written is removed.
"""

from tactile_studio.storage.exchange.importers._common import ImportFormatError, labelled_runs
from tactile_studio.storage.exchange.importers.datasets import (
    COST_GESTURES,
    HAART_GESTURES,
    import_cost,
    import_haart,
)
from tactile_studio.storage.exchange.importers.shearsense import (
    import_shearsense,
    import_shearsense_file,
    shearsense_trials,
)

__all__ = ["COST_GESTURES", "HAART_GESTURES", "ImportFormatError", "import_cost",
           "import_haart", "import_shearsense", "import_shearsense_file", "labelled_runs",
           "shearsense_trials"]
