"""Pure computation: drawing-machine models, sketch retrieval, guided exploration, fabrication geometry,
contraption scenarios, simulation, success probability, optimization and robustness.

Nothing in here touches a device or a user interface: ``design`` imports none of ``station``, ``drivers``,
``calibration``, ``projector`` or ``textual`` (enforced by ``tests/test_layering.py``).
"""
