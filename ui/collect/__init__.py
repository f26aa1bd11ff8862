"""The collection screens: the experimenter console and its setup page, the participant
screen, the trial log, the beep, and the ways in (the main window's menu, ``collect``).

``app`` (entry points) -> ``console`` (the window) -> ``setup``, ``log``, ``participant``
(+ ``participant_cards``), ``view`` (snapshot -> what the screens show), ``paint``,
``beep``. See docs/collect-screens.md.
"""
