"""The station's service layer: each area's work as plain functions and small classes.

A service takes typed inputs, returns typed results, raises the packages' own errors (design, drivers, and
:class:`station.errors.ServiceError`, whose messages never name a command-line flag) and reports
progress through one callback. ``station.commands`` turns argparse into service calls and results into text or
JSON; ``station.tui.screens`` call the same services from workers. Screens never import ``station.commands``
(``tests/test_layering.py`` checks it).
"""
