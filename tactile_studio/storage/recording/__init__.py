"""A recording: the recorder (frames from the engine into a session file), what a recording
books in the sensor logbook, and the frame sources that replay files. The top room of
storage: it uses the formats, the books and the exchange formats.
"""
