"""The lab's books on its sensors: the logbook (which sensor, its calibrations, hours of use),
the file it is kept in, and storing a new calibration as a sensor's active one. Independent
of the file formats.
"""
