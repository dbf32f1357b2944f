"""The station's Textual terminal UI: one screen module per area in :mod:`station.tui.screens`."""
