"""Area screens of the TUI; see :mod:`station.tui.registry` for the module contract."""
