"""MJCF composition of the swarm with dm_control's PyMJCF (docs/design.md, "the rooms").

PyMJCF is used only to build XML: the XML is compiled with ``mujoco.MjModel``
directly, because ``dm_control.mjcf.Physics`` is broken with mujoco 4
(docs/libraries.md). Each drone is ``assets/quadrotor.xml`` attached under its own
namespace (``leader/``, ``follower1/``, ...), so names come out scoped
(``leader/U1``, ``follower3/body``).
"""

from __future__ import annotations

import copy
import dataclasses
import logging
import os
import threading
from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

# dm_control is used only for PyMJCF. Its renderer module opens an EGL display when it is
# imported with MUJOCO_GL=egl and raises ImportError where EGL is missing, which would make
# the whole package unusable (and opens a second EGL display for nothing). MuJoCo has
# already read MUJOCO_GL above; import dm_control with its rendering disabled.
_mujoco_gl = os.environ.get("MUJOCO_GL")
os.environ["MUJOCO_GL"] = "disable"
try:
    from dm_control import mjcf
finally:
    if _mujoco_gl is None:
        del os.environ["MUJOCO_GL"]
    else:
        os.environ["MUJOCO_GL"] = _mujoco_gl

from ..errors import UserError
from ..resources import QUADROTOR_XML
from .params import DEFAULT_PARAMS, QuadParams

#: Where MuJoCo's warnings go (:func:`route_mujoco_warnings`).
MUJOCO_LOG = logging.getLogger("swarm_mj.mujoco")


def _mujoco_warning(message: str) -> None:
    MUJOCO_LOG.warning("MuJoCo: %s", message)


def route_mujoco_warnings() -> None:
    """Send MuJoCo's warnings to :data:`MUJOCO_LOG`. Without a handler MuJoCo appends each to
    ``MUJOCO_LOG.TXT`` in the working directory (a test run left one in the checkout), and whether
    dm_control's import installs one is dm_control's choice, not ours to rely on. The
    divergence warnings are also counted in ``MjData.warning``, which ``Sim.check`` turns into
    :class:`~swarm_mj.errors.SimulationDiverged` naming them. Done once, here, after dm_control's
    import (every simulator is built by this module)."""
    mujoco.set_mju_user_warning(_mujoco_warning)


route_mujoco_warnings()

LEADER_RGBA = (0.85, 0.15, 0.15, 1.0)
FOLLOWER_RGBA = (0.15, 0.45, 0.85, 1.0)
INTEGRATORS = {
    "RK4": mujoco.mjtIntegrator.mjINT_RK4,
    "Euler": mujoco.mjtIntegrator.mjINT_EULER,
    "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
}


#: Compiled swarm models kept for later builds in this process (docs/design.md, "Start-up and the step's own cost").
WORLD_CACHE_SIZE = 16


class _Built:
    """The last :data:`WORLD_CACHE_SIZE` compiled models with their XML, by everything that makes them
    (:func:`_cache_key`), least recently used dropped first. A kept model is never handed out:
    :func:`build_world` returns a copy (``mj_copyModel``), so a caller writing its model (the solid
    floor's gate does) cannot change a later build. Thread-safe (a lock around the dictionary)."""

    def __init__(self, size: int) -> None:
        self.size = size
        self._items: OrderedDict[tuple, tuple[mujoco.MjModel, str]] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, key: tuple) -> tuple[mujoco.MjModel, str] | None:
        with self._lock:
            hit = self._items.get(key)
            if hit is not None:
                self._items.move_to_end(key)
            return hit

    def put(self, key: tuple, built: tuple[mujoco.MjModel, str]) -> None:
        with self._lock:
            self._items[key] = built
            while len(self._items) > self.size:
                self._items.popitem(last=False)

    def clear(self) -> None:
        with self._lock:
            self._items.clear()

    def __len__(self) -> int:
        return len(self._items)


_BUILT = _Built(WORLD_CACHE_SIZE)


def clear_world_cache() -> None:
    """Forget the compiled models kept by :func:`build_world` (the next build composes and compiles again)."""
    _BUILT.clear()


@dataclass(frozen=True)
class WorldSpec:
    """Everything a swarm model is built from: :func:`build_world`'s checked arguments (see there)."""

    n_drones: int
    positions: np.ndarray  # (n, 3) initial centre-of-mass positions
    yaws: np.ndarray  # (n,) initial yaws (rad)
    names: tuple[str, ...]  # (n,) the drones' names
    params: QuadParams
    timestep: float
    integrator: str
    collisions: bool
    asset_path: Path
    floor: bool
    torque_motors: str
    ground: bool
    motor_tau: float
    contact_groups: int | None


def _cache_key(spec: WorldSpec) -> tuple | None:
    """Everything a built model depends on, exactly: the starts and yaws as their float64 bytes, the
    other arguments (the vehicle's every field) by ``repr`` (exact for floats; -0.0 and 0.0 differ),
    the asset file's path and bytes (an edited file is another key). None when the asset cannot be
    read (then the build says why)."""
    try:
        asset_bytes = spec.asset_path.read_bytes()
    except OSError:
        return None
    vehicle = (type(spec.params).__qualname__, dataclasses.astuple(spec.params))  # every field, whatever its repr shows
    scalars = tuple(
        vehicle if f.name == "params" else getattr(spec, f.name)
        for f in dataclasses.fields(spec)
        if f.name not in ("positions", "yaws", "asset_path")
    )
    return (spec.positions.tobytes(), spec.yaws.tobytes(), repr(scalars), str(spec.asset_path), asset_bytes)


def default_names(n_drones: int) -> list[str]:
    """``leader`` then ``follower1..n-1`` (the paper's UAV_L, UAV_F1..)."""
    return ["leader"] + [f"follower{k}" for k in range(1, n_drones)]


@dataclass
class World:
    """A compiled swarm model and what is needed to address each drone in it."""

    model: mujoco.MjModel
    names: list[str]  # (n,)
    params: QuadParams
    body_ids: np.ndarray  # (n,) id of each drone's massive body (xfrc_applied row)
    geom_drone: np.ndarray  # (ngeom,) drone index owning each geom, -1 for the world
    initial_positions: np.ndarray  # (n, 3)
    initial_yaws: np.ndarray  # (n,)
    xml: str

    @property
    def n_drones(self) -> int:
        return len(self.names)


def _drawn_part(drone: mjcf.RootElement, name: str):  # noqa: ANN202 - a PyMJCF element or None
    """A part of the drone that is only drawn: a site in the bundled asset, a geom in an older custom one."""
    part = drone.find("site", name)
    return part if part is not None else drone.find("geom", name)


def _drone_mjcf(
    name: str, params: QuadParams, rgba: Sequence[float], asset: Path, *, ground: bool = False, motor_tau: float = 0.0
) -> mjcf.RootElement:
    if not asset.exists():
        raise UserError(f"quadrotor asset not found: {asset}")
    try:
        drone = mjcf.from_path(str(asset))
    except Exception as exc:  # malformed XML
        raise UserError(f"cannot read quadrotor asset {asset}: {exc}") from None
    drone.model = name
    body = drone.find("body", "body")
    if body is None or drone.find("site", "com") is None:
        raise UserError(f"quadrotor asset {asset} must define body 'body' and site 'com'")
    body.inertial.mass = params.m
    body.inertial.diaginertia = [params.Ix, params.Iy, params.Iz]
    L = params.L
    gears = {"U1": [0, 0, 1, 0, 0, 0], "U2": [0, 0, 0, L, 0, 0], "U3": [0, 0, 0, 0, L, 0], "U4": [0, 0, 0, 0, 0, L]}
    for act, gear in gears.items():
        motor = drone.find("actuator", act)
        if motor is None:
            raise UserError(f"quadrotor asset {asset} must define motor actuator {act}")
        motor.gear = gear
    # The drawn parts, the contact disc and the rotor plane scale with the arm (docs/vehicles.md):
    # s = L / 0.25 is 1.0 for the paper's drone, whose asset sizes are kept as written.
    s = params.size_scale
    for k, (x, y) in enumerate((params.rotor_dirs * L).tolist(), start=1):  # the vehicle's layout ("+", "x")
        rotor = _drawn_part(drone, f"rotor{k}")
        if rotor is not None:
            rotor.pos = [x, y, s * rotor.pos[2] if rotor.pos is not None else 0.0]
            if rotor.tag == "site" and rotor.dclass is not None and rotor.dclass.site.size is not None:
                rotor.size = [params.rotor_radius, s * rotor.dclass.site.size[1]]
    plane = drone.find("geom", "rotor_plane")
    if plane is not None:
        _collision_body(plane, params)
    for part in ("hub", "nose"):
        el = _drawn_part(drone, part)
        if el is not None and s != 1.0:
            el.size = [v * s for v in el.size]
            if el.pos is not None:
                el.pos = [v * s for v in el.pos]
    if motor_tau > 0:
        # First-order rotor dynamics (docs/aero.md): MuJoCo integrates act' = (ctrl − act)/τ and applies
        # gear·act. The mixing is linear, so filtering U1..U4 is filtering each rotor's thrust.
        for act, gear in gears.items():
            old = drone.find("actuator", act)
            site = old.site
            old.remove()
            drone.actuator.add(
                "general",
                name=act,
                site=site,
                gear=gear,
                dyntype="filter",
                dynprm=[float(motor_tau)],
                gainprm=[1.0],
                biastype="none",
            )
    if ground:
        _landing_gear(drone, s)
    hub = _drawn_part(drone, "hub")
    if hub is not None:
        hub.rgba = list(rgba)
    for arm in ("arm_x", "arm_y"):
        g = drone.find("geom", arm)
        if g is not None:
            g.size = [L if arm == "arm_x" else s * g.size[0], L if arm == "arm_y" else s * g.size[1], s * g.size[2]]
            if params.layout == "x":  # the arms from rotor to rotor: turned 45° about z
                g.euler = [0, 0, 45]
    return drone


def _landing_gear(drone: mjcf.RootElement, s: float) -> None:
    """Add the landing gear to ``drone`` (``s``: its ``size_scale``) and let its rotor disc touch the floor."""
    # Landing gear (docs/aero.md): a strut under the hub and a square skid plate at its foot. The
    # skid touches only the floor: collision bit 4 (the floor has contype 4, the skid conaffinity 4
    # and contype 0). The rotor disc (the drone's outline) also gets conaffinity bit 4, so that a
    # tilted drone hits the floor with it; drone-drone pairs are unchanged (bit 1). One geom per
    # drone (the skid): every geom costs MuJoCo bounding-volume and collision work at each RK4
    # stage, so the strut, which only has to be seen, is a site (docs/aero.md, "Cost").
    from .aero.ground import SKID_HALF, SKID_HALF_Z, SKID_Z, STRUT_RADIUS

    body = drone.find("body", "body")
    body.add(
        "site",
        name="strut",
        type="capsule",
        fromto=[0, 0, -0.02 * s, 0, 0, SKID_Z * s],
        size=[STRUT_RADIUS * s],
        group=1,
        rgba=[0.2, 0.2, 0.25, 1],
    )
    body.add(
        "geom",
        name="skid",
        type="box",
        size=[SKID_HALF * s, SKID_HALF * s, SKID_HALF_Z * s],
        pos=[0, 0, SKID_Z * s],
        euler=[0, 0, 45],
        contype=0,
        conaffinity=4,
        group=1,
        density=0,
        rgba=[0.2, 0.2, 0.25, 1],
    )
    disc = drone.find("geom", "rotor_plane")
    if disc is not None:
        disc.conaffinity = int(disc.conaffinity if disc.conaffinity is not None else 1) | 4


def _collision_body(plane, params: QuadParams) -> None:  # noqa: ANN001 - plane: a PyMJCF geom
    """The colliding disc (``rotor_plane``) of radius ``contact_radius``: without ``height`` the asset's
    thickness and height above the centre of mass scaled by ``size_scale`` (the paper drone's disc, bit for
    bit); with ``height`` h (m) a cylinder h tall whose bottom is the plane the drone rests on, the foot
    of its landing gear (``REST_HEIGHT`` × ``size_scale`` below the centre of mass; docs/vehicles.md)."""
    s = params.size_scale
    if params.height is None:
        plane.size = [params.contact_radius, s * plane.size[1]]
        if plane.pos is not None:
            plane.pos = [p * s for p in plane.pos]
        return
    from .aero.ground import REST_HEIGHT

    h = float(params.height)
    plane.size = [params.contact_radius, h / 2]
    plane.pos = [0.0, 0.0, h / 2 - REST_HEIGHT * s]


#: The solid floor's contype: collision bit 4, which the skid's and the rotor disc's conaffinity hold (_drone_mjcf).
_FLOOR_CONTYPE = 4


def _take_colliders(drone: mjcf.RootElement, floor_bits: int = 0) -> list[tuple[str, int, int]]:
    """The drone's geoms that collide (contype or conaffinity nonzero, own or from their class), as (name,
    contype, conaffinity); their contype is set to 0 and their conaffinity to its ``floor_bits`` (the solid
    floor's contype, 0 without one): drone–drone contacts then come from explicit pairs only, floor contacts
    from the masks as before."""
    out = []
    for geom in drone.find_all("geom"):
        ct = geom.contype if geom.contype is not None else (geom.dclass.geom.contype if geom.dclass else None)
        ca = (
            geom.conaffinity
            if geom.conaffinity is not None
            else (geom.dclass.geom.conaffinity if geom.dclass else None)
        )
        ct, ca = (1 if ct is None else int(ct)), (1 if ca is None else int(ca))
        if ct or ca:
            if geom.name is None:
                raise UserError("every colliding geom of the quadrotor asset needs a name (contact pairs)")
            geom.contype = 0
            geom.conaffinity = ca & floor_bits
            out.append((geom.name, ct, ca))
    return out


def build_world(
    n_drones: int = 6,
    *,
    positions: np.ndarray | Sequence[Sequence[float]] | None = None,
    yaws: np.ndarray | Sequence[float] | None = None,
    names: Sequence[str] | None = None,
    params: QuadParams = DEFAULT_PARAMS,
    timestep: float = 0.005,
    integrator: str = "RK4",
    collisions: bool = True,
    asset: str | Path | None = None,
    floor: bool = True,
    torque_motors: str = "joint",
    ground: bool = False,
    motor_tau: float = 0.0,
    contact_groups: int | None = None,
) -> World:
    """Compose ``n_drones`` quadrotors into one MuJoCo model.

    positions: (n, 3) initial centre-of-mass positions (default: a row 1 m apart).
    collisions: False disables all contacts (used for independent copies, e.g. FPA).
    torque_motors: ``"joint"`` (default) moves the pure-torque motors U2..U4 from the site
    "com" onto the drone's free joint, with the same gear (0, 0, 0, L·e_i): MuJoCo's free-joint
    rotational dofs are in the body frame, which is the site's frame, so the torque is the same
    body-frame L·U (tested to 1e-12 against ``"site"``), but MuJoCo computes it in O(1) instead
    of through a 3×nv site Jacobian per motor (6 drones: mj_step 14 % faster; the cost of site
    motors grows with the square of the number of drones). U1, a force along body z, stays on
    the site: a free joint's translational dofs are in the world frame. ``"site"``: all four on
    the site, as in the asset.
    ground: a solid floor (it touches each drone's rotor disc) and a landing gear on each drone
    (``swarm_mj.physics.aero.ground``); False (the paper) leaves the floor drawn but never touched.
    motor_tau: rotor time constant (s); > 0 makes U1..U4 first-order filtered actuators
    (``dyntype="filter"``), 0 (the paper) ideal motors.
    contact_groups: None (default): every two drones may touch (each geom's contype/conaffinity).
    k: the drones form k groups of n/k consecutive drones (independent copies of one swarm, e.g.
    :class:`~swarm_mj.wrappers.vector.SwarmVectorEnv`) and only drones of the same group touch:
    the colliding geoms' contype/conaffinity are cleared and every pair of them on two drones of
    one group becomes an explicit ``<pair>`` (condim 3, friction 1: the same contact as the
    geoms' defaults). 32 contype bits cannot separate more than 32 groups; explicit pairs can.

    The composed and compiled model is kept (the last :data:`WORLD_CACHE_SIZE`, keyed by every
    argument above exactly and the asset file's bytes, not files it includes): a later build with
    the same arguments in this process copies it (``mj_copyModel``, 0.5 ms) instead of composing it
    with PyMJCF and compiling it again (60 ms for six drones). The copy is the same model bit for
    bit, and every build returns its own copy, so nothing written to one world's model reaches
    another (:func:`clear_world_cache` forgets them).
    """
    names, positions, yaws = _checked_world(n_drones, names, positions, yaws, timestep, integrator)
    asset_path = Path(asset) if asset is not None else QUADROTOR_XML
    _check_motors(n_drones, motor_tau, torque_motors, contact_groups)
    spec = WorldSpec(
        n_drones=n_drones,
        positions=positions,
        yaws=yaws,
        names=tuple(names),
        params=params,
        timestep=timestep,
        integrator=integrator,
        collisions=collisions,
        asset_path=asset_path,
        floor=floor,
        torque_motors=torque_motors,
        ground=ground,
        motor_tau=motor_tau,
        contact_groups=contact_groups,
    )
    key = _cache_key(spec)
    built = _BUILT.get(key) if key is not None else None
    if built is None:
        built = _compose(spec)
        if key is not None:
            _BUILT.put(key, built)
    cached, xml = built
    model = copy.copy(cached)  # mj_copyModel: the cached model is never handed out, so never mutated

    body_ids, geom_drone = _drone_ids(model, names)
    return World(
        model=model,
        names=names,
        params=params,
        body_ids=body_ids,
        geom_drone=geom_drone,
        initial_positions=positions.copy(),
        initial_yaws=yaws.copy(),
        xml=xml,
    )


def _checked_world(
    n_drones: int,
    names: Sequence[str] | None,
    positions: np.ndarray | Sequence[Sequence[float]] | None,
    yaws: np.ndarray | Sequence[float] | None,
    timestep: float,
    integrator: str,
) -> tuple[list[str], np.ndarray, np.ndarray]:
    """:func:`build_world`'s drones checked: (names, positions (n, 3), yaws (n,)), defaults filled in."""
    if not isinstance(n_drones, (int, np.integer)) or n_drones < 1:
        raise UserError(f"n_drones must be an integer >= 1, got {n_drones!r}")
    if not (np.isfinite(timestep) and timestep > 0):
        raise UserError(f"timestep must be a positive number of seconds, got {timestep!r}")
    if integrator not in INTEGRATORS:
        raise UserError(f"unknown integrator {integrator!r}; choose one of {sorted(INTEGRATORS)}")
    names = list(names) if names is not None else default_names(n_drones)
    if len(names) != n_drones or len(set(names)) != n_drones:
        raise UserError(f"need {n_drones} distinct drone names, got {names!r}")
    if positions is None:
        positions = np.column_stack([np.arange(n_drones, dtype=float), np.zeros(n_drones), np.zeros(n_drones)])
    positions = np.asarray(positions, dtype=float)
    if positions.shape != (n_drones, 3) or not np.isfinite(positions).all():
        raise UserError(f"positions must be a finite ({n_drones}, 3) array, got shape {positions.shape}")
    yaws = np.zeros(n_drones) if yaws is None else np.asarray(yaws, dtype=float)
    if yaws.shape != (n_drones,) or not np.isfinite(yaws).all():
        raise UserError(f"yaws must be a finite ({n_drones},) array, got {yaws.tolist()!r}")
    return names, positions, yaws


def _check_motors(n_drones: int, motor_tau: float, torque_motors: str, contact_groups: int | None) -> None:
    """:func:`build_world`'s motors and contact groups checked (:class:`UserError` naming the argument)."""
    if not (np.isfinite(motor_tau) and motor_tau >= 0):
        raise UserError(f"motor_tau must be a time constant >= 0 s, got {motor_tau!r}")
    if torque_motors not in ("joint", "site"):
        raise UserError(f"torque_motors must be 'joint' or 'site', got {torque_motors!r}")
    if contact_groups is not None and (
        not isinstance(contact_groups, (int, np.integer)) or contact_groups < 1 or n_drones % contact_groups
    ):
        raise UserError(f"contact_groups must divide the {n_drones} drones, got {contact_groups!r}")


def _drone_ids(model: mujoco.MjModel, names: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
    """(body ids (n,), the drone index of every geom (ngeom,), −1 for the floor and the world's)."""
    body_ids = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"{n}/body") for n in names])
    if (body_ids < 0).any():
        raise UserError("compiled model lacks a drone body named '<drone>/body'")
    geom_drone = np.full(model.ngeom, -1, dtype=np.int64)
    for k, bid in enumerate(body_ids):
        geom_drone[model.geom_bodyid == bid] = k
    return body_ids, geom_drone


def _compose(spec: WorldSpec) -> tuple[mujoco.MjModel, str]:
    """The swarm's MJCF composed with PyMJCF and compiled: (model, xml), from :func:`build_world`'s checked
    arguments."""
    arena = mjcf.RootElement(model="swarm")
    arena.option.timestep = spec.timestep
    arena.option.integrator = spec.integrator
    arena.option.gravity = [0.0, 0.0, -spec.params.g]
    arena.option.density = 0.0  # fluid model off: drag enters through xfrc_applied
    arena.option.viscosity = 0.0
    if not spec.collisions:
        arena.option.flag.contact = "disable"
    arena.visual.headlight.ambient = [0.4, 0.4, 0.4]
    arena.visual.headlight.diffuse = [0.6, 0.6, 0.6]
    arena.visual.quality.shadowsize = 2048
    getattr(arena.visual, "global").offwidth = 1920
    getattr(arena.visual, "global").offheight = 1080
    arena.asset.add(
        "texture",
        name="grid",
        type="2d",
        builtin="checker",
        rgb1=[0.82, 0.85, 0.88],
        rgb2=[0.72, 0.75, 0.78],
        width=512,
        height=512,
        mark="edge",
        markrgb=[0.6, 0.6, 0.65],
    )
    arena.asset.add("material", name="grid", texture="grid", texrepeat=[1, 1], texuniform=True, reflectance=0.05)
    arena.asset.add(
        "texture",
        name="sky",
        type="skybox",
        builtin="gradient",
        rgb1=[0.55, 0.7, 0.9],
        rgb2=[0.95, 0.97, 1.0],
        width=256,
        height=256,
    )
    if spec.ground:
        # A solid floor (aero presets with ground = true, docs/aero.md): it touches each drone's rotor
        # disc and landing skid (collision bit 4, see _drone_mjcf).
        arena.worldbody.add(
            "geom", name="floor", type="plane", size=[0, 0, 0.05], material="grid", contype=4, conaffinity=0, group=0
        )
    elif spec.floor:
        # The floor is seen but never touched: contacts are drone-drone only (docs/interpretations.md §1),
        # and a drone below the floor is reported as a divergence by the simulator.
        arena.worldbody.add(
            "geom", name="floor", type="plane", size=[0, 0, 0.05], material="grid", contype=0, conaffinity=0, group=0
        )
    arena.worldbody.add(
        "light", name="sun", pos=[0, 0, 12], dir=[0, 0, -1], directional=True, diffuse=[0.6, 0.6, 0.6], castshadow=True
    )

    frames = []
    colliders: list[list[tuple[str, int, int]]] = []  # per drone: (full name, contype, conaffinity), contact_groups
    for k, name in enumerate(spec.names):
        rgba = LEADER_RGBA if k == 0 else FOLLOWER_RGBA
        drone = _drone_mjcf(name, spec.params, rgba, spec.asset_path, ground=spec.ground, motor_tau=spec.motor_tau)
        if spec.contact_groups is not None and spec.collisions:
            floor_bits = _FLOOR_CONTYPE if spec.ground else 0
            colliders.append([(f"{name}/{g}", ct, ca) for g, ct, ca in _take_colliders(drone, floor_bits)])
        frame = arena.worldbody.attach(drone)
        frame.pos = spec.positions[k]
        c, s = np.cos(spec.yaws[k] / 2), np.sin(spec.yaws[k] / 2)
        frame.quat = [c, 0.0, 0.0, s]
        free = frame.add("freejoint", name=f"{name}_free")
        if spec.torque_motors == "joint":
            for act in ("U2", "U3", "U4"):
                motor = drone.find("actuator", act)
                motor.site = None
                motor.joint = free
        frames.append(frame)
    arena.worldbody.add("camera", name="track", mode="targetbodycom", target=frames[0], pos=[-7.0, -7.0, 6.0], fovy=50)

    xml = arena.to_xml_string()
    if colliders:
        assert spec.contact_groups is not None  # colliders are only collected with contact_groups
        # written into the XML directly: PyMJCF's own pair elements cost O(pairs · geoms) to resolve
        size = spec.n_drones // spec.contact_groups
        pairs = [  # the pairs MuJoCo's contype/conaffinity test lets collide
            f'<pair geom1="{ga}" geom2="{gb}" condim="3" friction="1 1 0.005 0.0001 0.0001"/>'
            for g in range(spec.contact_groups)
            for a in range(g * size, (g + 1) * size)
            for b in range(a + 1, (g + 1) * size)
            for ga, cta, caa in colliders[a]
            for gb, ctb, cab in colliders[b]
            if (cta & cab) or (ctb & caa)
        ]
        head, tail = xml.rsplit("</mujoco>", 1)
        xml = head + "  <contact>\n    " + "\n    ".join(pairs) + "\n  </contact>\n</mujoco>" + tail
    try:
        model = mujoco.MjModel.from_xml_string(xml, arena.get_assets())
    except Exception as exc:
        raise UserError(f"MuJoCo could not compile the swarm model: {exc}") from None
    return model, xml
