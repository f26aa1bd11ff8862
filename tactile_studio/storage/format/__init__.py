"""The file formats: the session file (its journal format, writer, reader ``SessionFile``, check,
compression, recovery, segments, trials and their checks, aux signals, sets of sessions, a
study's summary), the guards on files and names from outside, and the collection protocol
file. The lowest room of storage: it imports no other.
"""
