"""The station's service layer: each area's work as plain functions and small classes.

A service takes typed inputs (a frozen request dataclass where a workflow has many options: ``FabricationRequest``,
``PredictionRequest``...), returns typed results, reports progress and hears a stop through one
:class:`common.progress.Reporter` passed as ``report=``, and raises only station errors: its public functions and
classes wear :func:`station.errors.station_errors`, which turns the packages' errors (design, drivers, calibration,
projector, vision, data files) into station errors with the same message, and it refuses input with a
:class:`station.errors.ServiceError`, whose message never names a command-line flag. ``station.commands`` turns
argparse into service calls and results into text or JSON; ``station.tui.screens`` call the same services from
workers; neither imports a package below the station (``tests/test_layering.py`` checks it).

A service's imports are at the top of its module, except a heavy library the module does not load otherwise: that
import waits inside the function that needs it, marked ``# heavy: scipy, shapely`` (the libraries it brings), so
that the command line's ``--help`` and the terminal UI's start, which import the services, stay quick.
"""
