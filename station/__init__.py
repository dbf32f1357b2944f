"""The station: the only package that wires ``design``, ``drivers``, ``calibration`` and ``projector`` together.
Textual TUI, ``station`` CLI, job orchestration and the trial database."""

__version__ = "0.2.0"
