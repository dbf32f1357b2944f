"""Seeing the station's tags: the AprilTag bitmaps the station prints and projects (:mod:`vision.tags`) and their
detection in a camera frame (:mod:`vision.detection`). Imports only ``common`` and third-party libraries, so that
guides (``projector``), measurement (``calibration``) and the station share one definition of a tag."""
