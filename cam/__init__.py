"""Tool paths: from plain polylines to the G-code programs a plotter or a laser runs.

- :mod:`cam.plot`: fit polylines to the paper, simplify them, write a plot job (pen up/down, feeds);
- :mod:`cam.layers`: a plot of several layers, one pen each, with a pen change between them;
- :mod:`cam.laser`: a laser job (engrave, then cut holes before outlines), its travel ordered (nearest neighbour,
  2-opt), checked against the work area and written for GRBL's dynamic power;
- :mod:`cam.place`: a written job moved and turned on the bed.

It sits above ``drivers``, whose G-code reader (:mod:`drivers.gcode`) and errors it uses: a tool path is written in the
machine's language, and the driver never needs to know how it was made. It takes plain numpy polylines, never a
design (the station hands them over).
"""
