"""The station's shared leaf: types every other package may use and that import nothing of the station.

``design`` and ``drivers`` must not import each other (``tests/test_layering.py``), yet both report progress the
same way; what they share lives here. Nothing in this package imports ``design``, ``drivers``, ``calibration``,
``projector``, ``station`` or a UI library.
"""
