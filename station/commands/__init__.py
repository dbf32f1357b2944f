"""One module per area of the ``station`` CLI; see :mod:`station.cli` for the module contract."""
