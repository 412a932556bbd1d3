"""Replay a run's log into a fresh MuJoCo model and draw frames (:class:`Replay`).

The logged states (one sample per control period) are written into the ``qpos`` of a fresh
``MjData`` of the same swarm model and drawn with MuJoCo's own renderer through EGL
(:func:`.gl.open_renderer`). Drawn on top of the model (user geoms added to the ``MjvScene``
after ``update_scene``): the leader's reference path, each drone's fading trail and a caption.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import mujoco
import numpy as np

from ..errors import UserError
from ..physics.params import DEFAULT_PARAMS, QuadParams
from .camera import CameraPath, nearest_index
from .gl import open_renderer
from .style import DEFAULT_SIZE, FOLLOWER_RGB, LEADER_RGB, REFERENCE_RGBA, VideoStyle


def _rgba(rgb: Sequence[float], a: float) -> np.ndarray:
    return np.array([rgb[0], rgb[1], rgb[2], a], dtype=np.float32)


def replay_world(log, *, ground: bool = False, params: QuadParams = DEFAULT_PARAMS):  # noqa: ANN201 - a World
    """The swarm a log replays into: its drones (names ``log.names``) at their first logged positions,
    drawn as the vehicle ``params`` (the run's, ``Scenario.params``: the model scaled to it,
    docs/vehicles.md), with the landing gear and the solid floor when ``ground`` (docs/aero.md)."""
    from ..physics.world import build_world

    p0 = np.nan_to_num(np.asarray(log.pos[0], float))
    return build_world(len(log.names), positions=p0, names=list(log.names), ground=ground, params=params)


class Replay:
    """Replays a :class:`~swarm_mj.experiments.runner.RunLog` into a MuJoCo model and renders frames.

    ``Replay(log)`` rebuilds the swarm with :func:`replay_world` (initial positions ``log.pos[0]``,
    names ``log.names``); pass ``world`` to reuse one. Use as a
    context manager (it holds an EGL context): ``with Replay(log, width=640, height=480) as
    r: image = r.render(20.0)``.
    """

    def __init__(
        self,
        log,
        world=None,
        *,
        width: int = DEFAULT_SIZE[0],
        height: int = DEFAULT_SIZE[1],
        style: VideoStyle | None = None,
    ) -> None:
        if len(log.t) < 1:
            raise UserError("the run has no samples to render")
        self.log = log
        self.style = style or VideoStyle()
        self.width, self.height = int(width), int(height)
        n = len(log.names)
        if world is None:
            world = replay_world(log)
        if world.n_drones != n:
            raise UserError(f"the world has {world.n_drones} drones, the log {n}")
        self.world = world
        self.model = model = world.model
        if model.nq != 7 * n:
            raise UserError("the model must hold only the drones' free joints (7 qpos per drone)")
        self.n = n
        self._tune_model(model)
        self.data = mujoco.MjData(model)
        self.camera = CameraPath.frame_swarm(log.t, log.pos, self.width / self.height, self.style)
        self.option = mujoco.MjvOption()
        self.renderer = open_renderer(model, self.width, self.height)
        if not self.style.shadows:
            self.renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = False
        self._colors = [LEADER_RGB if i == 0 else FOLLOWER_RGB for i in range(n)]
        self._ref = self._reference_vertices()
        self._caption_font: Any = None
        self.title: str | None = None  # drawn in the caption when set
        self.last_index = -1

    # -- model look -----------------------------------------------------------------
    def _tune_model(self, model: mujoco.MjModel) -> None:
        """Rendering-only changes to this replay's copy of the model (physics untouched)."""
        st = self.style
        model.vis.global_.fovy = st.fovy_deg
        # znear/zfar are in units of the model's extent: 5 cm to 300 m with extent >= 10 m.
        model.stat.extent = max(float(model.stat.extent), 10.0)
        model.vis.map.znear = 0.005
        model.vis.map.zfar = 30.0
        model.vis.map.shadowclip = 1.0  # shadow map covers +-extent around the (moving) sun
        model.vis.quality.offsamples = max(0, int(st.samples))
        # Softer headlight, a darker floor: the default look is washed out in a still.
        model.vis.headlight.ambient[:] = 0.32
        model.vis.headlight.diffuse[:] = 0.45
        model.vis.headlight.specular[:] = 0.1
        if model.nlight:
            model.light_diffuse[:] = 0.55
            model.light_specular[:] = 0.1
        self._light_pos0 = model.light_pos.copy()
        for m in range(model.nmat):
            if mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_MATERIAL, m) == "grid":
                model.mat_rgba[m] = (0.86, 0.88, 0.92, 1.0)
                model.mat_texrepeat[m] = (1.0, 1.0)
        # Rotor discs and hub in the drone's colour (the asset draws every rotor light blue). They are
        # sites in the bundled asset (drawn only, assets/quadrotor.xml), geoms in an older custom one.
        body_ids = getattr(self.world, "body_ids", None)
        if body_ids is not None:
            drone_of = {int(b): i for i, b in enumerate(body_ids)}
            for obj, count, bodyid, rgba in (
                (mujoco.mjtObj.mjOBJ_GEOM, model.ngeom, model.geom_bodyid, model.geom_rgba),
                (mujoco.mjtObj.mjOBJ_SITE, model.nsite, model.site_bodyid, model.site_rgba),
            ):
                for g in range(count):
                    i = drone_of.get(int(bodyid[g]), -1)
                    if i < 0:
                        continue
                    name = mujoco.mj_id2name(model, obj, g) or ""
                    rgb = LEADER_RGB if i == 0 else FOLLOWER_RGB
                    if name.endswith(("rotor1", "rotor2", "rotor3", "rotor4")):
                        rgba[g] = (*rgb, 0.6)
                    elif name.endswith("hub"):
                        rgba[g] = (*rgb, 1.0)
                    elif name.endswith("nose"):  # heading marker: white, so red means "leader" only
                        rgba[g] = (0.97, 0.97, 0.97, 1.0)

    def _reference_vertices(self) -> np.ndarray:
        log, st = self.log, self.style
        ref = np.asarray(log.slot[:, 0], float)
        ref = ref[np.isfinite(ref).all(axis=1)]
        if len(ref) < 2:
            return ref
        dt = float(np.median(np.diff(log.t))) if len(log.t) > 1 else 0.01
        step = max(1, int(round(st.reference_dt / dt)), int(math.ceil(len(ref) / 600)))
        idx = np.unique(np.r_[np.arange(0, len(ref), step), len(ref) - 1])
        return ref[idx]

    # -- state ----------------------------------------------------------------------
    def set_state(self, j: int) -> None:
        """Write log sample ``j`` into qpos (7 per drone: position, unit quaternion w x y z)."""
        qpos = self.data.qpos.reshape(self.n, 7)
        qpos[:, 0:3] = np.nan_to_num(self.log.pos[j])
        q = np.nan_to_num(self.log.quat[j])
        norm = np.linalg.norm(q, axis=1, keepdims=True)
        qpos[:, 3:7] = np.where(norm > 1e-9, q / np.maximum(norm, 1e-9), [1.0, 0.0, 0.0, 0.0])
        self.data.qvel[:] = 0.0
        self.data.time = float(self.log.t[j])
        # The sun follows the camera's target so the swarm stays inside its shadow map.
        if self.model.nlight:
            la = self.camera.lookat[j]
            self.model.light_pos[:, 0:2] = self._light_pos0[:, 0:2] + la[0:2]
        mujoco.mj_forward(self.model, self.data)

    # -- extra geoms ----------------------------------------------------------------
    def _add_line(self, scn, a, b, width_px: float, rgba) -> bool:
        if scn.ngeom >= scn.maxgeom:
            return False
        if not (np.isfinite(a).all() and np.isfinite(b).all()) or np.linalg.norm(b - a) < 1e-6:
            return True
        g = scn.geoms[scn.ngeom]
        mujoco.mjv_initGeom(g, mujoco.mjtGeom.mjGEOM_LINE, self._zero3, self._zero3, self._eye9, rgba)
        mujoco.mjv_connector(g, mujoco.mjtGeom.mjGEOM_LINE, width_px, a, b)
        g.category = mujoco.mjtCatBit.mjCAT_DECOR
        g.castshadow = False
        scn.ngeom += 1
        return True

    def _add_disc(self, scn, centre, radius, rgba) -> None:
        if scn.ngeom >= scn.maxgeom or not np.isfinite(centre).all():
            return
        g = scn.geoms[scn.ngeom]
        mujoco.mjv_initGeom(
            g,
            mujoco.mjtGeom.mjGEOM_CYLINDER,
            np.array([radius, 0.003, 0.0]),
            np.asarray(centre, float),
            self._eye9,
            rgba,
        )
        g.category = mujoco.mjtCatBit.mjCAT_DECOR
        g.castshadow = False
        scn.ngeom += 1

    _zero3 = np.zeros(3)
    _eye9 = np.eye(3).ravel()

    def _px(self, width_at_720: float) -> float:
        return max(1.0, width_at_720 * self.height / 720.0)

    def _decorate(self, j: int) -> None:
        scn = self.renderer.scene
        st, log = self.style, self.log
        if st.reference and len(self._ref) > 1:
            # dashed: every other segment, so the leader's own (solid) trail shows through
            rgba = np.array(REFERENCE_RGBA, dtype=np.float32)
            w = self._px(st.reference_px)
            for s in range(0, len(self._ref) - 1, 2):
                if not self._add_line(scn, self._ref[s], self._ref[s + 1], w, rgba):
                    break
        if st.trails and j > 0:
            t = log.t
            now = float(t[j])
            dt = float(np.median(np.diff(t))) if len(t) > 1 else 0.01
            stride = max(1, int(round(st.trail_dt / dt)))
            # vertices on a fixed grid of sample indices (no flicker), then the current sample
            k0 = nearest_index(t, max(float(t[0]), now - st.trail_s))
            first = int(math.ceil(k0 / stride) * stride)
            idx = np.unique(np.clip(np.r_[k0, np.arange(first, j, stride), j], 0, j))
            if len(idx) > 1:
                age = (now - t[idx[1:]]) / max(st.trail_s, 1e-9)
                alpha = 0.15 + 0.8 * (1.0 - np.clip(age, 0.0, 1.0))
                w = self._px(st.trail_px)
                for i in range(self.n):
                    pts = log.pos[idx, i]
                    rgb = self._colors[i]
                    for s in range(len(idx) - 1):
                        self._add_line(scn, pts[s], pts[s + 1], w, _rgba(rgb, float(alpha[s])))
        if st.markers:
            for i in range(self.n):
                self._add_disc(scn, log.pos[j, i] + np.array([0.0, 0.0, -0.03]), 0.16, _rgba(self._colors[i], 0.9))

    def _caption(self, image: np.ndarray, j: int) -> np.ndarray:
        try:
            from PIL import Image, ImageDraw, ImageFont
        except ImportError:  # pragma: no cover - Pillow comes with imageio
            return image
        h = self.height
        size = max(10, int(round(h / 34)))
        if self._caption_font is None:
            try:
                self._caption_font = ImageFont.load_default(size=size)
            except TypeError:  # pragma: no cover - old Pillow
                self._caption_font = ImageFont.load_default()
        font = self._caption_font
        img = Image.fromarray(image)
        draw = ImageDraw.Draw(img, "RGBA")
        pad = max(4, size // 2)
        text = f"t = {self.log.t[j]:6.2f} s"
        name = getattr(self, "title", None)
        if name:
            text = f"{name}   {text}"
        items: list[tuple[Any, str]] = [
            (LEADER_RGB, "leader"),
            (FOLLOWER_RGB, "followers"),
            (REFERENCE_RGBA[:3], "reference path"),
        ]
        if self.style.trails:
            items.append((None, f"trails: last {self.style.trail_s:g} s"))
        widths = [
            int(draw.textlength(label, font=font)) + int(size * (1.3 if rgb else 0) + size * 1.2)
            for rgb, label in items
        ]
        box_w = max(int(draw.textlength(text, font=font)), sum(widths) - int(size * 1.2)) + 2 * pad
        box_h = int(size * 2.6) + 2 * pad
        draw.rounded_rectangle(
            [pad // 2, pad // 2, pad // 2 + box_w, pad // 2 + box_h], radius=pad, fill=(255, 255, 255, 170)
        )
        ink = (20, 20, 30, 255)
        draw.text((pad, pad), text, fill=ink, font=font)
        y = pad + int(size * 1.4)
        x = pad
        for rgb, label in items:
            if rgb is not None:
                col = tuple(int(255 * c) for c in rgb) + (255,)
                draw.rectangle([x, y + size * 0.25, x + size * 0.9, y + size * 0.95], fill=col)
                x += int(size * 1.3)
            draw.text((x, y), label, fill=ink, font=font)
            x += int(draw.textlength(label, font=font)) + int(size * 1.2)
        return np.asarray(img)

    # -- frames ---------------------------------------------------------------------
    def update(self, time: float, *, decorate: bool = True) -> int:
        """Set the replayed state and scene to the sample nearest ``time``; returns its index."""
        j = nearest_index(self.log.t, time)
        self.set_state(j)
        self.renderer.update_scene(self.data, camera=self.camera.mjv_camera(j), scene_option=self.option)
        if decorate:
            self._decorate(j)
        self.last_index = j
        return j

    def render(self, time: float, *, caption: bool | None = None, segmentation: bool = False) -> np.ndarray:
        """The frame at ``time`` (nearest log sample): (H, W, 3) uint8, or (H, W, 2) segmentation.

        Segmentation images (object id, object type per pixel) show the model's geoms only:
        the trails, reference path and markers are not model objects and are left out.
        """
        j = self.update(time, decorate=not segmentation)
        if segmentation:
            self.renderer.enable_segmentation_rendering()
            try:
                return self.renderer.render()
            finally:
                self.renderer.disable_segmentation_rendering()
        image = self.renderer.render()
        if self.style.caption if caption is None else caption:
            image = self._caption(image, j)
        return image

    @property
    def glcamera(self):
        """The OpenGL camera of the last frame (for :func:`project_points`).

        ``scene.camera`` holds the two stereo eyes, each shifted by half the model's
        inter-pupillary distance; without stereo MuJoCo draws with their average.
        """
        cams = self.renderer.scene.camera
        return mujoco.mjv_averageCamera(cams[0], cams[1])

    def close(self) -> None:
        r = getattr(self, "renderer", None)
        if r is not None:
            r.close()
            self.renderer = None

    def __enter__(self) -> Replay:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __del__(self) -> None:  # pragma: no cover - best effort
        try:
            self.close()
        except Exception:
            pass
