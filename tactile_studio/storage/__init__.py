"""Session files (HDF5), the recorder, importers and exporters."""

from tactile_studio.storage.recorder import Recorder
from tactile_studio.storage.session import Session, read_journal
from tactile_studio.storage.session_writer import SCHEMA_VERSION, SessionWriter

__all__ = ["SCHEMA_VERSION", "Recorder", "Session", "SessionWriter", "read_journal"]
