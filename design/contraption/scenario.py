"""Scenario files: the scene, the causal graph and the design space of a chain-reaction contraption (thesis 4.3).

A scenario is a data file (TOML or JSON, never executed). Its top-level tables:

``[scenario]``
    ``name``, ``description`` (optional).
``[settings]`` (optional)
    ``time_step`` (s, default 1/500), ``event_timeout`` (s, default 2), ``max_duration`` (s, default 4),
    ``gravity`` (m/s², default -9.81, along z), ``solver_iterations`` (default 50),
    ``overlap_tolerance`` (fraction of the smaller body's smallest dimension tolerated as interpenetration,
    default 0.05), ``ignore_overlap`` (list of ``[a, b]`` object pairs allowed to interpenetrate).
``[materials.NAME]`` (optional)
    What a kind of part is made of: ``friction``, ``rolling_friction``, ``spinning_friction``, ``restitution``,
    ``linear_damping``, ``angular_damping``, each a number or an uncertain value ``{ value = 0.6, range = [0.3,
    0.9] }`` (the range is what simulator calibration may fit; see :mod:`design.contraption.materials`).
``[[objects]]``
    ``name``, ``type`` (a primitive, see :data:`PRIMITIVES`), ``parent`` (optional: the transform is then in the
    parent's frame), ``[objects.transform]`` (``x``, ``y``, ``z`` in m; ``heading``, ``pitch``, ``roll`` in degrees),
    ``[objects.ranges]`` (``component = [min, max]``: makes the component a design parameter),
    ``[objects.shape]`` (the primitive's shape parameters), ``material`` (a material's name: its values are the
    object's physics), ``[objects.physics]`` (its keys override the material's) (``mass`` — 0 or absent is
    static —, ``friction``, ``rolling_friction``, ``spinning_friction``, ``restitution``, ``linear_damping``,
    ``angular_damping``), ``[objects.tag]`` (optional AprilTag: ``id``, ``x``, ``y``, ``z``, ``size``: its centre
    in the part's frame, on the face towards the camera for the guide's view, and its black square's edge, m;
    ``angle`` in degrees turns its printed "up" away from the part's local +y (top view) or +z (side view),
    counter-clockwise as the camera sees it; a DominoRun takes an array of one or two such tables instead, each with
    ``body``, the domino it sits on (0 the first, -1 the last), its place in that domino's frame: the run is then
    checked by its first and last dominoes; tags are not part of the content hash),
    ``sleeping`` (true: the bodies start asleep and are not simulated until something touches them — for parts
    resting stably, a large speed-up; default true for DominoRun, false otherwise).
``[[events]]``
    ``name``, ``type`` (see :data:`EVENTS`), the event's parameters (object names; a domino of a run is
    ``run[0]``, ``run[-1]``), ``after`` (parent events; none for the single root), ``join`` (``"all"``: every parent
    must succeed, the thesis's rule; ``"any"``: one parent is enough), ``timeout`` (s), ``duration`` (s: the
    condition must hold that long), ``label`` (words shown to people).
``[layouts.NAME]`` (optional)
    Named layouts: ``"object.component" = value`` in real units (m, degrees); absent parameters keep the transform's
    value. The examples carry a ``success`` and a ``failure`` layout.

Angles: ``heading`` turns about +z, ``pitch`` about +x, ``roll`` about +y (right-handed; the rotation is
``Rz(heading) Rx(pitch) Ry(roll)``, Panda3D's HPR order). With z up and the layout in the x-z plane, ``roll`` is the
rotation in that plane: a positive roll tilts the +x end down.

The design space lists the ranged components in file order of the objects, and for each object in the order

The code is split by topic; this module is the format's description and re-exports the public names of:

- :mod:`~design.contraption.schema`: the tables of primitives and events and the kinds of their fields;
- :mod:`~design.contraption.model`: the frozen data (:class:`Scenario`, :class:`ObjectSpec`, ...) and the hash;
- :mod:`~design.contraption.design_space`: :class:`DesignSpace`;
- :mod:`~design.contraption.validation`: :func:`load_scenario`, :func:`scenario_from_data` (parsing and fields),
  :func:`with_physics`;
- :mod:`~design.contraption.graph`: references between objects and the causal graph's checks.

Layout files are read by :mod:`design.contraption.layout_io`.
"""

from __future__ import annotations

from design.contraption.design_space import DesignSpace
from design.contraption.errors import LayoutError, ScenarioFormatError
from design.contraption.graph import resolve_body_ref
from design.contraption.model import (
    EventSpec,
    ObjectSpec,
    Physics,
    Scenario,
    Settings,
    Tag,
    Transform,
    content_hash,
    domino_count,
)
from design.contraption.schema import (
    ANGLE_KEYS,
    EVENT_COMMON,
    EVENTS,
    PHYSICS_DEFAULTS,
    PHYSICS_KEYS,
    PRIMITIVES,
    REQUIRED,
    TRANSFORM_KEYS,
    UNPLACED,
    Y_AXIS,
    Kind,
    Param,
    Primitive,
)
from design.contraption.validation import design_space_of, load_scenario, parse_text, scenario_from_data, with_physics

__all__ = [
    "ANGLE_KEYS",
    "EVENTS",
    "EVENT_COMMON",
    "PHYSICS_DEFAULTS",
    "PHYSICS_KEYS",
    "PRIMITIVES",
    "REQUIRED",
    "TRANSFORM_KEYS",
    "UNPLACED",
    "Y_AXIS",
    "DesignSpace",
    "EventSpec",
    "Kind",
    "LayoutError",
    "ObjectSpec",
    "Param",
    "Physics",
    "Primitive",
    "Scenario",
    "ScenarioFormatError",
    "Settings",
    "Tag",
    "Transform",
    "content_hash",
    "design_space_of",
    "domino_count",
    "load_scenario",
    "parse_text",
    "resolve_body_ref",
    "scenario_from_data",
    "with_physics",
]
