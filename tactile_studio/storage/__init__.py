"""Storage, in four rooms in order: ``recording`` (the recorder and what it books), ``exchange``
(importers, exporters, other tools' formats), ``format`` (the session file, the protocol file)
and ``books`` (the sensor logbook). ``SessionFile``, ``SessionWriter`` and ``Recorder`` are
re-exported here."""

from tactile_studio.storage.format.session_file import SessionFile, read_journal
from tactile_studio.storage.format.session_writer import SCHEMA_VERSION, SessionWriter
from tactile_studio.storage.recording.recorder import Recorder

__all__ = ["SCHEMA_VERSION", "Recorder", "SessionFile", "SessionWriter", "read_journal"]
