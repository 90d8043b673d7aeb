"""The viewer's web page: a viser server drawing a :class:`~tabletop.viewer.session.ViewerSession`.

The map's voxels are drawn first, straight from the file (:func:`~tabletop.mapping.persistence.
read_map_preview`), as one point cloud; the map itself (its encoders) loads behind it, and the
parts that need it (queries, instances, obstacles, sounds, reaches, evaluation goals) come
alive when it has. Voxels, heat, obstacles and frustums are each one scene node (a point cloud
or one set of line segments), never a node per voxel. The Panda is its URDF's link meshes, posed
by the arm model's forward kinematics.
"""

from __future__ import annotations

import contextlib
import io
import math
import threading
import time

import numpy as np

from tabletop.viewer import draw
from tabletop.viewer.session import KINDS, QueryOutcome, ReachOutcome, ViewerSession

__all__ = ["Viewer"]

_FRAMES = 30.0  # animation frames per second
#: The background work (the robot's meshes, the map's encoders) waits this long [s] for a
#: browser to connect, then this long [s] more for it to draw the map: imports and model loading
#: would otherwise hold the interpreter while the server sends the page (and share two cores
#: with a browser drawing in software).
FIRST_PICTURE_WAIT_S = 5.0
AFTER_CONNECT_S = 1.5
_GREY = (225, 225, 228)
_TARGET = (230, 20, 20)


def _wxyz(R: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_matrix(R).as_quat()
    return np.array([w, x, y, z])


def _fmt(p) -> str:
    return "(" + ", ".join(f"{v:+.3f}" for v in np.asarray(p, float)) + ") m"


class Viewer:
    """The viewer of one map, served by viser on ``host``:``port``.

    Args:
        session: what to show (:class:`ViewerSession`).
        host: the address to bind (127.0.0.1: this machine only).
        port: the port (0: a free one).
        load: draw the robot and load the map in a background thread now (False: the robot
            is drawn now; the caller calls :meth:`start_loading`).
        animation_s: the longest a reach's animation takes [s] (frames are skipped to fit).
    """

    def __init__(
        self,
        session: ViewerSession,
        host: str = "127.0.0.1",
        port: int = 8080,
        load: bool = True,
        animation_s: float = 4.0,
    ) -> None:
        import viser

        self.s = session
        self.animation_s = float(animation_s)
        if port == 0:
            port = _free_port(host)
        with contextlib.redirect_stdout(io.StringIO()):  # viser's banner: we print the address
            self.server = viser.ViserServer(host=host, port=port, verbose=False)
        self.server.gui.configure_theme(
            control_width="large", show_logo=False, dark_mode=False, show_share_button=False
        )
        self.scene = self.server.scene
        self.gui = self.server.gui
        self.busy = threading.Lock()
        self.last: QueryOutcome | None = None
        self.reaches = 0
        """How many "go"s finished (for tests and scripts)."""
        self.asked = 0
        """How many queries finished."""
        self._audio = None
        self.groups: dict = {}
        self.links: dict = {}
        self.connected = threading.Event()
        """Set when the first browser has connected."""
        self.server.on_client_connect(lambda _: self.connected.set())
        self._draw_map()  # the first picture: before anything else
        self._camera()
        self._build_gui()
        if load:
            self.start_loading()
        else:
            self._draw_robot()
            self._draw_frustums()

    @property
    def url(self) -> str:
        return f"http://{self.server.get_host()}:{self.server.get_port()}"

    # ------------------------------------------------------------------ the first picture
    def _group(self, name: str, visible: bool = True):
        """An empty frame ``name`` whose children are one layer: shown, hidden and cleared
        together."""
        h = self.scene.add_frame(name, show_axes=False, visible=visible)
        self.groups[name] = h
        return h

    def _clear(self, name: str) -> None:
        """Remove every node of layer ``name`` (it stays, as shown or hidden as it was)."""
        old = self.groups.get(name)
        visible = True if old is None else old.visible
        if old is not None:
            old.remove()
        self._group(name, visible)

    def _set_visible(self, name: str, on: bool) -> None:
        if name not in self.groups:
            self._group(name)
        self.groups[name].visible = bool(on)

    def _draw_map(self) -> None:
        # no image-based lighting: prefiltering the environment map takes a software-WebGL
        # browser (no GPU) half a minute; an ambient and the default lights draw the arm
        self.scene.configure_environment_map(None)
        self.scene.configure_default_lights(True, cast_shadow=False)
        self.scene.add_light_ambient("/lights/ambient", intensity=1.6)
        p = self.s.preview
        size = self.s.grid.voxel_size
        self.h_map = self.scene.add_point_cloud(
            "/map/voxels", p.centers.astype(np.float32), p.colors, point_size=size,
            point_shape="square", point_shading="flat",
        )  # fmt: skip

    def _camera(self) -> None:
        g = self.s.grid
        lo, hi = np.array(g.lower), np.array(g.upper)
        cam = self.server.initial_camera
        if self.s.room:
            c = (lo + hi) / 2
            span = float(max(hi[:2] - lo[:2]))
            cam.position = (c[0] - 0.55 * span, c[1] - 0.55 * span, 0.85 * span)
            cam.look_at = (c[0], c[1], 0.0)
        else:
            cam.position = (1.45, -0.95, 0.85)
            cam.look_at = (0.3, 0.0, 0.05)
        cam.fov = math.radians(50)

    # ------------------------------------------------------------------ the panel
    def _build_gui(self) -> None:
        gui = self.gui
        self.md_status = gui.add_markdown(f"**{self.s.title}**  \nloading the map's encoders ...")
        with gui.add_folder("Ask the map"):
            self.t_query = gui.add_text("request", initial_value="")
            self.d_kind = gui.add_dropdown("read as", tuple(KINDS), initial_value="request")
            self.t_near = gui.add_text("near", initial_value="")
            self.d_near = gui.add_dropdown("near as", tuple(KINDS)[1:], initial_value="object")
            self.b_ask = gui.add_button("Ask", disabled=True)
            self.md_query = gui.add_markdown(
                "A request in words is read by the robot's reader (objects, sounds, areas, "
                "'near', instructions); or read it as one modality."
            )
        with gui.add_folder("Reach"):
            what = "base" if self.s.room else "arm"
            self.b_go = gui.add_button("go", disabled=True, hint=f"the {what} reaches the target")
            self.md_go = gui.add_markdown(f"Ask first; then **go** moves the {what} there.")
        with gui.add_folder("Layers"):
            self.c_map = gui.add_checkbox("map voxels", True)
            self.d_colour = gui.add_dropdown(
                "colour", ("fused colour", "occupancy (height)", "instances"),
                initial_value="fused colour",
            )  # fmt: skip
            self.c_heat = gui.add_checkbox("heatmap", True)
            self.c_labels = gui.add_checkbox("instance labels", False)
            self.c_obstacles = {
                name: gui.add_checkbox(f"obstacles: {name}", False)
                for name in self.s.embodiment_names()
            }
            self.c_robot = gui.add_checkbox("robot", True)
            self.c_frustums = gui.add_checkbox("camera path", True)
            self.c_sounds = gui.add_checkbox("sounds", True)
        self.f_sounds = gui.add_folder("Sounds")
        with self.f_sounds:
            self.d_sound = gui.add_dropdown("segment", ("(loading)",))
            self.b_play = gui.add_button("play", disabled=True)
            self.md_sound = gui.add_markdown("Click a sound's sphere in the scene to hear it.")
        self.s_frame = None
        if self.s.recording_path is not None:
            with gui.add_folder("Scan", expand_by_default=False):
                self.s_frame = gui.add_slider("frame", 0, 1, 1, 0, disabled=True)
        self.d_goal = None
        if self.s.eval_dir is not None:
            with gui.add_folder("Evaluation"):
                self.d_goal = gui.add_dropdown("goal", ("(loading)",))
                self.b_prev = gui.add_button("previous goal", disabled=True)
                self.b_next = gui.add_button("next goal", disabled=True)
                self.md_goal = gui.add_markdown("")
        self._wire()

    def _wire(self) -> None:
        self.b_ask.on_click(lambda _: self._in_thread(self._ask))
        self.b_go.on_click(lambda _: self._in_thread(self._go))
        self.c_map.on_update(lambda _: setattr(self.h_map, "visible", self.c_map.value))
        self.d_colour.on_update(lambda _: self._recolour())
        self.c_heat.on_update(lambda _: self._set_visible("/heat", self.c_heat.value))
        for name in ("/heat", "/target", "/robot", "/camera", "/sounds", "/labels", "/eval",
                     "/paths"):  # fmt: skip
            self._group(name)
        self.c_labels.on_update(lambda _: self._labels())
        for name, box in self.c_obstacles.items():
            box.on_update(lambda _, n=name: self._in_thread(lambda: self._obstacles(n)))
        self.c_robot.on_update(lambda _: self._set_visible("/robot", self.c_robot.value))
        self.c_frustums.on_update(lambda _: self._set_visible("/camera", self.c_frustums.value))
        self.c_sounds.on_update(lambda _: self._set_visible("/sounds", self.c_sounds.value))
        self.b_play.on_click(lambda _: self._play(self._sound_index()))
        if self.s_frame is not None:
            self.s_frame.on_update(lambda _: self._frame(int(self.s_frame.value)))
        if self.d_goal is not None:
            self.d_goal.on_update(lambda _: self._in_thread(self._show_goal))
            self.b_prev.on_click(lambda _: self._step_goal(-1))
            self.b_next.on_click(lambda _: self._step_goal(+1))

    def _in_thread(self, fn) -> None:
        threading.Thread(target=fn, daemon=True).start()

    # ------------------------------------------------------------------ loading
    def start_loading(self) -> None:
        """In the background: draw the robot and the camera path, then load the map (its
        encoders) and fill in what needs it."""
        self._in_thread(self._background)

    def _background(self) -> None:
        # the first picture first: the robot, the camera path and the map's encoders come once
        # a browser has had a moment to draw the map (or a few seconds after the start), the
        # encoders below the server's and the browser's priority
        if self.connected.wait(FIRST_PICTURE_WAIT_S):
            time.sleep(AFTER_CONNECT_S)
        self._draw_robot()
        self._draw_frustums()
        _lower_this_threads_priority()
        self._load()

    def _load(self) -> None:
        if not self.s.ready.is_set():
            self.s.load()
        if self.s.map is None:
            self.md_status.content = (
                f"**{self.s.title}**  \nthe map could not be loaded: {self.s.error}"
            )
            return
        self._draw_frustums()
        self._draw_sounds()
        if self.s_frame is not None and self.s.recording is not None:
            self.s_frame.max = max(len(self.s.recording) - 1, 1)
            self.s_frame.disabled = False
        self._warm_up()
        self.b_ask.disabled = False
        rec = "" if self.s.recording is None else f", recording of {len(self.s.recording)} frames"
        note = f"  \n{self.s.error}" if self.s.error else ""
        self.md_status.content = f"**{self.s.title}**{rec}  \nready{note}"
        if self.d_goal is not None:
            self._load_goals()

    def _warm_up(self) -> None:
        """One query before the first person's: the reader and the object module read their
        vocabularies once (seconds), not while someone waits."""
        voc = list(self.s.map.config.objects)
        try:
            self.s.query(voc[0] if voc else "table", "request")
        except Exception:  # a warm-up failing shows on the first real query
            pass

    # ------------------------------------------------------------------ the map's layers
    def _recolour(self) -> None:
        mode = self.d_colour.value
        p = self.s.preview
        if mode == "occupancy (height)":
            self.h_map.colors = draw.height_colours(p.centers[:, 2])
        elif mode == "instances":
            cols = np.full((len(p.centers), 3), 150, np.uint8)
            ids = p.instance
            uniq = np.unique(ids[ids >= 0])
            pal = draw.distinct_colours(len(uniq))
            for k, i in enumerate(uniq):
                cols[ids == i] = pal[k]
            self.h_map.colors = cols
        else:
            self.h_map.colors = p.colors

    def _labels(self) -> None:
        self._clear("/labels")
        if not self.c_labels.value:
            return
        if self.s.map is None:
            self.md_status.content += "  \n(instances need the loaded map)"
            return
        for inst in self.s.instances():
            top = np.array(
                [(inst.lo[0] + inst.hi[0]) / 2, (inst.lo[1] + inst.hi[1]) / 2, inst.hi[2]]
            )
            self.scene.add_label(
                f"/labels/{inst.id}", f"{inst.label} ({inst.probability:.2f})",
                position=top + np.array([0.0, 0.0, 0.02]), anchor="bottom-center",
            )  # fmt: skip

    def _obstacles(self, name: str) -> None:
        node = f"/obstacles/{name.replace(' ', '_')}"
        on = self.c_obstacles[name].value
        if node in self.groups or not on:
            self._set_visible(node, on)
            return
        if self.s.map is None:
            return
        self._group(node)
        emb = next(e for e in self.s.embodiments() if e.name == name)
        centres, size = self.s.obstacles(emb)
        colour = (255, 140, 0) if list(self.c_obstacles).index(name) == 0 else (150, 60, 220)
        self.scene.add_point_cloud(
            f"{node}/voxels", centres.astype(np.float32), colour, point_size=size * 1.02,
            point_shape="square", point_shading="flat",
        )  # fmt: skip

    # ------------------------------------------------------------------ the robot
    def _draw_robot(self) -> None:
        if self.s.room:
            self._draw_base()
            return
        from tabletop.arm.model import HOME_Q, PandaModel

        self.model = PandaModel()
        links = {}
        for lm in draw.panda_link_meshes():
            links[lm.link] = self.scene.add_mesh_simple(
                f"/robot/{lm.link}", lm.vertices, lm.faces, color=_GREY, cast_shadow=False,
                receive_shadow=False,
            )  # fmt: skip
        self.links = links
        self.pose_arm(HOME_Q)

    def pose_arm(self, q) -> None:
        """Put the drawn Panda at joint configuration ``q`` (7,) [rad]."""
        T = self.model.fk_frames(q, tuple(self.links))
        with self.server.atomic():
            for name, h in self.links.items():
                h.position = T[name][:3, 3]
                h.wxyz = _wxyz(T[name][:3, :3])

    def _draw_base(self) -> None:
        import trimesh

        from tabletop.base import TABLETOP_BASE

        r = TABLETOP_BASE.radius
        body = trimesh.creation.cylinder(radius=r, height=0.25, sections=32)
        body.apply_translation([0, 0, 0.125])
        nose = trimesh.creation.box((r, 0.04, 0.04))
        nose.apply_translation([r / 2, 0, 0.27])
        mast = trimesh.creation.cylinder(radius=0.02, height=1.0, sections=12)
        mast.apply_translation([0, 0, 0.75])
        mesh = trimesh.util.concatenate([body, nose, mast])
        self.h_base = self.scene.add_mesh_simple(
            "/robot/base", np.asarray(mesh.vertices, np.float32), np.asarray(mesh.faces),
            color=(60, 120, 200), cast_shadow=False, receive_shadow=False,
        )  # fmt: skip
        p = self.s.base_start()
        self.pose_base(p.x, p.y, p.yaw)

    def pose_base(self, x: float, y: float, yaw: float) -> None:
        self.h_base.position = (x, y, 0.0)
        self.h_base.wxyz = (math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2))

    def _draw_frustums(self) -> None:
        T, K, size = self.s.camera_poses()
        if not len(T):
            return
        if K is None:  # the map's fused frames: their poses only; a generic camera
            K = np.array([[200.0, 0, 160], [0, 200.0, 120], [0, 0, 1]])
            size = (320, 240)
        pick = T[:: max(1, len(T) // 24)]
        depth = 0.4 if self.s.room else 0.05
        segs = draw.frustum_segments(pick, K, size, depth)
        self.scene.add_line_segments(
            "/camera/frustums", segs.astype(np.float32), (90, 90, 110), thickness=1.0,
            thickness_units="screen",
        )  # fmt: skip
        self.scene.add_line_segments(
            "/camera/path", draw.path_segments(T[:, :3, 3]).astype(np.float32), (40, 160, 200),
            thickness=1.5, thickness_units="screen",
        )  # fmt: skip
        self._K, self._size, self._T = K, size, T

    def _frame(self, i: int) -> None:
        """Show the scan at frame ``i``: its camera and the arm's configuration then."""
        T = self._T
        i = int(np.clip(i, 0, len(T) - 1))
        seg = draw.frustum_segments(T[i : i + 1], self._K, self._size, 0.3 if self.s.room else 0.12)
        self.scene.add_line_segments(
            "/camera/now", seg.astype(np.float32), (255, 60, 0), thickness=3.0,
            thickness_units="screen",
        )  # fmt: skip
        jp = self.s.joint_path()
        if jp is not None and self.links:
            self.pose_arm(jp[i])
        elif self.s.room and self.s.recording is not None:
            H = self.s.recording.T_world_hand[i]
            self.pose_base(H[0, 3], H[1, 3], math.atan2(H[1, 0], H[0, 0]))

    # ------------------------------------------------------------------ sounds
    def _draw_sounds(self) -> None:
        self.sounds = self.s.sounds()
        names = []
        for snd in self.sounds:
            h = self.scene.add_icosphere(
                f"/sounds/{snd.index}", 0.012 if not self.s.room else 0.08, (250, 170, 0),
                position=snd.position, cast_shadow=False, receive_shadow=False,
            )  # fmt: skip
            h.on_click(lambda _, i=snd.index: self._play(i))
            score = "" if np.isnan(snd.score) else f" {snd.score:.2f}"
            short = snd.label.removeprefix("the sound of ").removeprefix("a ").removeprefix("an ")
            self.scene.add_label(
                f"/sounds/{snd.index}/label", f"{short}{score}", anchor="bottom-center",
                position=(0, 0, 0.02),
            )  # fmt: skip
            names.append(f"{snd.index}: {snd.label} ({snd.start_s:.1f}-{snd.end_s:.1f} s)")
        if any(snd.samples is not None for snd in self.sounds):
            self._audio_api()  # the browser's audio runtime, before the first click
        if names:
            self.d_sound.options = tuple(names)
            self.d_sound.value = names[0]
            self.b_play.disabled = False
        else:
            self.d_sound.options = ("(no sounds in this map)",)

    def _sound_index(self) -> int:
        try:
            return int(str(self.d_sound.value).split(":", 1)[0])
        except ValueError:
            return -1

    def _play(self, i: int) -> None:
        """Play segment ``i`` where it was heard (positional audio through viser-audio;
        without it, as a plain audio element in the panel)."""
        if not 0 <= i < len(getattr(self, "sounds", ())):
            return
        snd = self.sounds[i]
        head = f"**{snd.label}**, heard {snd.start_s:.1f}-{snd.end_s:.1f} s at {_fmt(snd.position)}"
        if snd.samples is None or not len(snd.samples):
            self.md_sound.content = f"{head}  \nno samples: open the viewer with --recording"
            return
        audio = self._audio_api()
        if audio is not None:
            clip = audio.add(
                f"/sounds/{i}/clip", snd.samples, snd.rate, positional=True, loop=False
            )
            clip.play()
            self.md_sound.content = f"{head}  \nplaying, placed where it was heard"
            return
        self.md_sound.content = f"{head}  \n" + _html_audio(snd.samples, snd.rate)

    def _audio_api(self):
        if self._audio is None:
            try:
                import viser_audio

                self._audio = viser_audio.AudioApi(self.server)
            except ImportError:
                self._audio = False
        return self._audio or None

    # ------------------------------------------------------------------ queries
    def ask(self, text: str, kind: str = "request", near: str = "", near_kind: str = "object"):
        """Ask the map (what the Ask button does) and draw the answer."""
        with self.busy:
            self.md_query.content = f"asking {text!r} ..."
            out = self.s.query(text, kind, near, near_kind)
            self.last = out
            self._draw_answer(out)
            self.b_go.disabled = not (out.found and len(out.targets))
            self.asked += 1
        return out

    def _ask(self) -> None:
        self.ask(self.t_query.value, self.d_kind.value, self.t_near.value, self.d_near.value)

    def _draw_answer(self, out: QueryOutcome, prefix: str = "") -> None:
        self._clear("/heat")
        self._clear("/target")
        if out.heat is not None:
            pos, cols, _ = draw.heat_voxels(out.heat, self.s.grid, self.s.linear)
            if len(pos):
                self.scene.add_point_cloud(
                    "/heat/voxels", pos.astype(np.float32), cols,
                    point_size=self.s.grid.voxel_size * 1.08, point_shape="square",
                    point_shading="flat",
                )  # fmt: skip
        r = 0.015 if not self.s.room else 0.1
        for k, t in enumerate(out.targets):
            self.scene.add_icosphere(
                f"/target/{k}", r, _TARGET, position=t, cast_shadow=False, receive_shadow=False
            )
            self.scene.add_label(
                f"/target/{k}/label", f"target {k + 1}" if len(out.targets) > 1 else "target",
                position=(0, 0, r * 1.5), anchor="bottom-center",
            )  # fmt: skip
        self.md_query.content = prefix + _answer_markdown(out)

    # ------------------------------------------------------------------ reaching
    def go(self) -> ReachOutcome | None:
        """Reach the last query's targets (what the go button does) and animate it."""
        out = self.last
        if out is None or not len(out.targets):
            self.md_go.content = "Ask the map first: there is no target."
            return None
        with self.busy:
            self.b_go.disabled = True
            what = "base drives" if self.s.room else "arm reaches"
            self.md_go.content = f"the {what} {len(out.targets)} target(s) ..."
            try:
                res = self.s.reach(out.targets)
            except Exception as e:  # shown in the page, not lost in a thread
                self.md_go.content = f"the reach failed: {type(e).__name__}: {e}"
                self.b_go.disabled = False
                return None
            self._animate(res)
            self.md_go.content = _reach_markdown(res)
            self.b_go.disabled = False
            self.reaches += 1
        return res

    def _go(self) -> None:
        self.go()

    def _animate(self, res: ReachOutcome) -> None:
        frames = res.frames
        if res.robot == "base":
            self._clear("/paths")
            for k, pl in enumerate(res.planned):
                if len(pl) > 1:
                    xyz = np.hstack([pl, np.full((len(pl), 1), 0.02)])
                    self.scene.add_line_segments(
                        f"/paths/planned{k}", draw.path_segments(xyz).astype(np.float32),
                        (20, 20, 20), thickness=2.0, thickness_units="screen",
                    )  # fmt: skip
            xyz = np.hstack([frames[:, :2], np.full((len(frames), 1), 0.03)])
            self.scene.add_line_segments(
                "/paths/driven", draw.path_segments(xyz).astype(np.float32), (60, 120, 200),
                thickness=4.0, thickness_units="screen",
            )  # fmt: skip
        n = len(frames)
        step = max(1, math.ceil(n / (_FRAMES * self.animation_s)))  # at most animation_s
        for f in [*frames[::step], frames[-1]]:
            if res.robot == "base":
                self.pose_base(*f[:3])
            else:
                self.pose_arm(f)
            time.sleep(1.0 / _FRAMES)

    # ------------------------------------------------------------------ evaluation
    def _load_goals(self) -> None:
        try:
            self.goals = self.s.eval_goals()
        except Exception as e:
            self.md_goal.content = str(e)
            return
        if not self.goals:
            self.md_goal.content = "no goals in that evaluation"
            return
        self.d_goal.options = tuple(f"{k + 1}. {g.label}" for k, g in enumerate(self.goals))
        self.d_goal.value = self.d_goal.options[0]
        self.b_prev.disabled = self.b_next.disabled = False
        if not self.goals[0].same_map:
            self.md_goal.content = "(none of its goals ran on this map: showing all)"

    def _goal_index(self) -> int:
        try:
            return int(str(self.d_goal.value).split(".", 1)[0]) - 1
        except ValueError:
            return -1

    def _step_goal(self, d: int) -> None:
        i = self._goal_index()
        if i < 0:
            return
        self.d_goal.value = self.d_goal.options[(i + d) % len(self.d_goal.options)]

    def _show_goal(self) -> None:
        i = self._goal_index()
        if not 0 <= i < len(getattr(self, "goals", ())):
            return
        g = self.goals[i]
        r = g.result
        self._clear("/eval")
        segs = [draw.box_segments(lo, hi) for lo, hi in r.get("truth") or []]
        if segs:
            self.scene.add_line_segments(
                "/eval/truth", np.concatenate(segs).astype(np.float32), (0, 170, 60),
                thickness=3.0, thickness_units="screen",
            )  # fmt: skip
        for key, colour, label in (
            ("target", (230, 20, 20), "predicted"), ("tcp", (30, 90, 230), "final TCP")
        ):  # fmt: skip
            p = r.get(key)
            if p is not None:
                self.scene.add_icosphere(
                    f"/eval/{key}", 0.012 if not self.s.room else 0.08, colour, position=p,
                    cast_shadow=False, receive_shadow=False,
                )  # fmt: skip
                self.scene.add_label(f"/eval/{key}/label", label, position=(0, 0, 0.02))
        lines = [
            f"**{r['goal_id']}** ({r.get('type')}): {r.get('text', '')!r}",
            f"status **{r.get('status')}**" + (" (success)" if r.get("success") else "")
            + (f": {r.get('reason')}" if r.get("reason") else ""),
        ]  # fmt: skip
        if r.get("error_m") is not None:
            lines.append(f"final TCP {r['error_m'] * 100:.1f} cm from the truth")
        if r.get("target_error_m") is not None:
            lines.append(f"predicted target {r['target_error_m'] * 100:.1f} cm from the truth")
        if r.get("reach"):
            lines.append(f"reach: {r['reach']}, route {r.get('route') or '-'}")
        lines.append(f"task {g.task} ({g.encoders} encoders)")
        self.md_goal.content = "  \n".join(lines) + "  \nheatmap: asking the map again ..."
        if self.s.map is None:
            return
        with self.busy:
            out = self.s.goal_query(g)
            self.last = out
            self._draw_answer(out)
            self.b_go.disabled = not (out.found and len(out.targets))
        self.md_goal.content = "  \n".join(lines) + (
            "" if out.found else f"  \nheatmap: {out.reason}"
        )

    # ------------------------------------------------------------------ running
    def close(self) -> None:
        with contextlib.redirect_stdout(io.StringIO()):
            self.server.stop()


def _answer_markdown(out: QueryOutcome) -> str:
    lines = []
    if out.found and len(out.targets):
        for k, t in enumerate(out.targets):
            lines.append(f"**target{' ' + str(k + 1) if len(out.targets) > 1 else ''}** {_fmt(t)}")
        if out.confidence is not None:
            lines.append(f"confidence **{out.confidence:.2f}**")
    elif out.found:
        lines.append("found, but the request moves nowhere")
    else:
        lines.append(f"**not found**: {out.reason}")
    for p in out.parts:
        status = "found" if p.found else f"not found ({p.reason})"
        lines.append(f"- {p.modality} {p.query!r}: confidence {p.confidence:.2f}, {status}")
    if out.code:
        lines.append("robot code (run dry):\n\n```python\n" + out.code.strip() + "\n```")
    lines.append(f"({out.seconds:.2f} s)")
    return "  \n".join(lines)


def _reach_markdown(res: ReachOutcome) -> str:
    lines = []
    for k, r in enumerate(res.results):
        head = f"target {k + 1}: " if len(res.results) > 1 else ""
        state = "**reached**" if r["reached"] else f"**not reached** ({r['reason']})"
        line = f"{head}{state}, error {r['error_m'] * 100:.1f} cm"
        if "clearance_m" in r:
            line += f", clearance {r['clearance_m'] * 100:.1f} cm"
        line += f", route {r['route']}"
        if r.get("contacts") is not None:
            line += f", contacts {r['contacts']}"
        lines.append(line)
        if r.get("note"):
            lines.append(f"  ({r['note']})")
    lines.append(f"ran on {res.simulator}")
    return "  \n".join(lines)


def _html_audio(samples: np.ndarray, rate: int) -> str:
    """An HTML audio element playing ``samples`` (a WAV in a data URL)."""
    import base64
    import io
    import wave

    pcm = (np.clip(samples, -1, 1) * 32767).astype("<i2").tobytes()
    buf = io.BytesIO()
    with wave.open(buf, "wb") as w:
        w.setnchannels(1)
        w.setsampwidth(2)
        w.setframerate(int(rate))
        w.writeframes(pcm)
    data = base64.b64encode(buf.getvalue()).decode()
    return f'<audio controls autoplay src="data:audio/wav;base64,{data}"></audio>'


def _lower_this_threads_priority(nice: int = 10) -> None:
    """Run the calling thread (and the threads it starts) at a lower priority: on Linux a
    thread's nice value is its own. Elsewhere nothing changes."""
    import os

    try:
        os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), nice)
    except (AttributeError, OSError):
        pass


def _free_port(host: str) -> int:
    import socket

    with socket.socket() as s:
        s.bind((host, 0))
        return int(s.getsockname()[1])
