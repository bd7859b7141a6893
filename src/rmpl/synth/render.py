"""Headless OpenGL rendering of posed bodies for MHP (moderngl over EGL).

One :class:`Renderer` holds one OpenGL context for its lifetime (creating a context costs far
more than a frame). It draws a batch of meshes, each seen by its own cameras, with rmpl's
pinhole: world -> camera ``x = R X + t``, then ``u = fx x/z + s y/z + cx``,
``v = fy y/z + cy``, with pixel ``(i, j)`` centred on ``u = i, v = j`` (OpenCV's convention;
rows from the top). Lens distortion is not rendered.

Each image gets a procedural background (gradient, smooth noise, colour patches; nothing
downloaded), and each body a random outfit (per-part vertex colours from
:data:`rmpl.synth.body.PARTS`) and random lighting (one key and one fill light, shared by all
views of a body, plus ambient).

:meth:`Renderer.render_scene` draws several bodies into each image with one depth buffer, so
they hide each other, and returns which body each pixel shows (an id mask).

Needs ``moderngl`` and an EGL driver (Debian: ``libegl1 libgl1-mesa-dri libegl-mesa0``;
software Mesa ``llvmpipe`` works, no GPU or display needed).

Shape glossary: ``B`` bodies (scenes), ``P`` bodies in a scene, ``V`` views per body (scene),
``N`` vertices, ``F`` faces.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "Lighting",
    "Renderer",
    "vertex_normals",
    "random_outfits",
    "random_lighting",
    "random_background",
    "gl_projection",
]

_VERTEX_SHADER = """
#version 330
uniform mat4 mvp;
in vec3 in_pos;
in vec3 in_normal;
in vec3 in_color;
out vec3 v_world;
out vec3 v_normal;
out vec3 v_color;
void main() {
    v_world = in_pos;
    v_normal = in_normal;
    v_color = in_color;
    gl_Position = mvp * vec4(in_pos, 1.0);
}
"""

_FRAGMENT_SHADER = """
#version 330
uniform vec3 eye;
uniform vec3 light_dir[2];
uniform vec3 light_color[2];
uniform vec3 ambient;
uniform float specular;
uniform float shininess;
uniform float body_alpha;  // 1 for one body; (person + 1) / 255 in a scene (an id mask)
in vec3 v_world;
in vec3 v_normal;
in vec3 v_color;
out vec4 f_color;
void main() {
    vec3 n = normalize(v_normal);
    vec3 view = normalize(eye - v_world);
    if (dot(n, view) < 0.0) n = -n;
    vec3 c = v_color * ambient * (0.8 + 0.2 * n.z);  // a little more light from the sky
    for (int i = 0; i < 2; i++) {
        float diffuse = max(dot(n, light_dir[i]), 0.0);
        vec3 h = normalize(light_dir[i] + view);
        float spec = specular * pow(max(dot(n, h), 0.0), shininess) * float(diffuse > 0.0);
        c += light_color[i] * (v_color * diffuse + spec);
    }
    f_color = vec4(clamp(c, 0.0, 1.0), body_alpha);
}
"""

_BACKGROUND_VERTEX = """
#version 330
in vec2 in_xy;
out vec2 v_uv;
void main() {
    v_uv = in_xy * 0.5 + 0.5;
    gl_Position = vec4(in_xy, 1.0, 1.0);
}
"""

_BACKGROUND_FRAGMENT = """
#version 330
uniform sampler2D image;
in vec2 v_uv;
out vec4 f_color;
void main() {
    f_color = vec4(texture(image, v_uv).rgb, 0.0);
}
"""


@dataclass(frozen=True)
class Lighting:
    """Lights of one body, in world coordinates.

    Attributes:
        directions: unit vectors towards the key and fill lights, shape (2, 3).
        colors: their RGB intensities, shape (2, 3).
        ambient: ambient RGB intensity, shape (3,).
        specular: specular strength.
        shininess: specular exponent.
    """

    directions: np.ndarray
    colors: np.ndarray
    ambient: np.ndarray
    specular: float = 0.1
    shininess: float = 16.0


def gl_projection(
    K: np.ndarray,
    R: np.ndarray,
    t: np.ndarray,
    size: tuple[int, int],
    near: float = 0.05,
    far: float = 100.0,
) -> np.ndarray:
    """OpenGL clip matrix that reproduces :func:`rmpl.geometry.camera.project`.

    Maps homogeneous world points to clip space so that window coordinates are
    ``(u + 0.5, v + 0.5)``: framebuffer row ``j`` is image row ``j`` from the top, read back
    without a flip.

    Args:
        K: (3, 3) pixels. R: (3, 3). t: (3,) metres. size: (width, height) pixels.

    Returns:
        Shape (4, 4), row-major (transpose before handing it to GLSL).

    >>> K = np.array([[100.0, 0, 50], [0, 100, 40], [0, 0, 1]])
    >>> M = gl_projection(K, np.eye(3), np.zeros(3), (100, 80))
    >>> c = M @ [0.1, 0.2, 2.0, 1.0]
    >>> window = (c[:2] / c[3] + 1) / 2 * [100, 80]  # framebuffer coordinates
    >>> np.round(window - 0.5, 9).tolist()  # (u, v)
    [55.0, 50.0]
    """
    W, H = size
    Rt = np.eye(4)
    Rt[:3, :3], Rt[:3, 3] = K @ R, K @ t  # -> (u z, v z, z, 1)
    A, B = (far + near) / (far - near), -2 * far * near / (far - near)
    C = np.array(
        [
            [2 / W, 0, 1 / W - 1, 0],
            [0, 2 / H, 1 / H - 1, 0],
            [0, 0, A, B],
            [0, 0, 1, 0],
        ]
    )
    return C @ Rt


def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals.

    Args:
        vertices: shape (B, N, 3). faces: shape (F, 3), counter-clockwise seen from outside.

    Returns:
        Shape (B, N, 3), float32.

    >>> v = np.array([[[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]]); f = np.array([[0, 1, 2]])
    >>> vertex_normals(v, f)[0, 0].tolist()
    [0.0, 0.0, 1.0]
    """
    B, N, _ = vertices.shape
    v = vertices[:, faces]  # (B, F, 3 corners, 3)
    fn = np.cross(v[:, :, 1] - v[:, :, 0], v[:, :, 2] - v[:, :, 0])  # (B, F, 3), 2x area
    index = (faces[None] + N * np.arange(B)[:, None, None]).ravel()  # (B * F * 3,)
    out = np.empty((B * N, 3))
    for c in range(3):
        w = np.repeat(fn[..., c], 3, axis=-1).ravel()  # each face's normal on its 3 corners
        out[:, c] = np.bincount(index, weights=w, minlength=B * N)
    out /= np.maximum(np.linalg.norm(out, axis=-1, keepdims=True), 1e-12)
    return out.reshape(B, N, 3).astype(np.float32)


_SKIN = (
    np.array(
        [
            [255, 224, 196],
            [241, 194, 125],
            [224, 172, 105],
            [198, 134, 66],
            [141, 85, 36],
            [92, 58, 38],
        ],
        float,
    )
    / 255
)
_HAIR = (
    np.array(
        [
            [20, 17, 15],
            [59, 48, 36],
            [106, 78, 66],
            [167, 133, 106],
            [220, 208, 186],
            [145, 85, 61],
            [180, 180, 180],
        ],
        float,
    )
    / 255
)


def _hsv_to_rgb(h: np.ndarray, s: np.ndarray, v: np.ndarray) -> np.ndarray:
    """HSV in [0, 1] to RGB in [0, 1], shape (*, 3)."""
    k = (np.array([5.0, 3.0, 1.0]) + h[..., None] * 6) % 6
    return v[..., None] - v[..., None] * s[..., None] * np.clip(np.minimum(k, 4 - k), 0, 1)


def random_outfits(
    parts: np.ndarray, num: int, rng: np.random.Generator | int | None = None
) -> np.ndarray:
    """Random skin, hair and clothes as vertex colours.

    Args:
        parts: part index of every vertex into :data:`rmpl.synth.body.PARTS`, shape (N,).
        num: bodies, B.
        rng: numpy Generator or seed.

    Returns:
        RGB in [0, 1], shape (B, N, 3), float32.
    """
    from rmpl.synth.body import PARTS

    rng = np.random.default_rng(rng)
    P = {name: i for i, name in enumerate(PARTS)}

    def pick(palette: np.ndarray, jitter: float) -> np.ndarray:
        a = rng.integers(0, len(palette) - 1, num)
        w = rng.uniform(0, 1, (num, 1))
        c = palette[a] * (1 - w) + palette[a + 1] * w
        return np.clip(c * rng.uniform(1 - jitter, 1 + jitter, (num, 3)), 0, 1)

    def cloth() -> np.ndarray:
        return _hsv_to_rgb(
            rng.uniform(0, 1, num), rng.beta(1.2, 2.0, num), rng.uniform(0.08, 0.95, num)
        )

    skin, hair = pick(_SKIN, 0.05), pick(_HAIR, 0.1)
    hair = np.where(rng.uniform(size=(num, 1)) < 0.1, skin, hair)  # bald
    top, bottom = cloth(), cloth()
    shoes = np.where(rng.uniform(size=(num, 1)) < 0.5, cloth() * 0.4, cloth())
    long_sleeves = rng.uniform(size=(num, 1)) < 0.5
    sleeveless = rng.uniform(size=(num, 1)) < 0.1
    shorts = rng.uniform(size=(num, 1)) < 0.25
    table = np.zeros((num, len(PARTS), 3))  # (B, parts, RGB) colour of each part
    for name in ("face", "neck", "hand"):
        table[:, P[name]] = skin
    table[:, P["hair"]] = hair
    table[:, P["eye"]] = 0.15
    table[:, P["torso"]] = top
    table[:, P["upper_arm"]] = np.where(sleeveless, skin, top)
    table[:, P["lower_arm"]] = np.where(long_sleeves & ~sleeveless, top, skin)
    table[:, P["upper_leg"]] = bottom
    table[:, P["lower_leg"]] = np.where(shorts, skin, bottom)
    table[:, P["foot"]] = shoes
    colors = table[:, np.asarray(parts, dtype=np.int64)]  # (B, N, 3)
    colors *= rng.uniform(0.94, 1.06, colors.shape[:2])[..., None]  # faint mottling
    return np.clip(colors, 0, 1).astype(np.float32)


def random_lighting(rng: np.random.Generator | int | None = None) -> Lighting:
    """A key light from above at a random azimuth, a weaker fill light and ambient."""
    rng = np.random.default_rng(rng)
    az = rng.uniform(0, 2 * np.pi, 2)
    el = np.radians(rng.uniform([15, -10], [80, 40]))
    directions = np.stack(
        [np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], axis=-1
    )  # (2, 3)
    tint = rng.uniform(0.85, 1.0, (2, 3))
    colors = tint * np.array([[rng.uniform(0.5, 0.9)], [rng.uniform(0.15, 0.4)]])
    ambient = rng.uniform(0.3, 0.55) * rng.uniform(0.9, 1.0, 3)
    return Lighting(
        directions,
        colors,
        ambient,
        specular=float(rng.uniform(0, 0.25)),
        shininess=float(rng.uniform(4, 40)),
    )


def random_background(
    width: int, height: int, rng: np.random.Generator | int | None = None
) -> np.ndarray:
    """A procedural backdrop: gradient, smooth noise and colour patches.

    Returns:
        RGB uint8, shape (height, width, 3). Draw it small and let the renderer upsample it
        (it is smooth on purpose, like an out-of-focus room).
    """
    rng = np.random.default_rng(rng)
    yy, xx = np.mgrid[0:height, 0:width] / max(width, height)
    angle = rng.uniform(0, 2 * np.pi)
    ramp = np.cos(angle) * xx + np.sin(angle) * yy
    ramp = (ramp - ramp.min()) / max(np.ptp(ramp), 1e-9)
    c0, c1 = _hsv_to_rgb(rng.uniform(0, 1, 2), rng.beta(1.2, 3.0, 2), rng.uniform(0.1, 1, 2))
    img = c0 + ramp[..., None] * (c1 - c0)  # (H, W, 3)
    # Smooth noise: a coarse random grid, bilinearly upsampled.
    gh, gw = rng.integers(2, 9, 2)
    grid = rng.normal(0, rng.uniform(0.03, 0.2), (gh + 1, gw + 1, 1))  # brightness
    grid = grid + rng.normal(0, 0.03, (gh + 1, gw + 1, 3))  # and a little colour
    gy, gx = yy * max(width, height) / height * gh, xx * max(width, height) / width * gw
    y0, x0 = np.minimum(gy.astype(int), gh - 1), np.minimum(gx.astype(int), gw - 1)
    fy, fx = (gy - y0)[..., None], (gx - x0)[..., None]
    img += (
        grid[y0, x0] * (1 - fy) * (1 - fx)
        + grid[y0 + 1, x0] * fy * (1 - fx)
        + grid[y0, x0 + 1] * (1 - fy) * fx
        + grid[y0 + 1, x0 + 1] * fy * fx
    )
    # Patches: rectangles (furniture, doors, posters) and ellipses.
    for _ in range(rng.integers(0, 9)):
        x_lo, x_hi = np.sort(rng.uniform(-0.1, 1.1, 2) * width)
        y_lo, y_hi = np.sort(rng.uniform(-0.1, 1.1, 2) * height)
        px, py = xx * max(width, height), yy * max(width, height)
        if rng.uniform() < 0.6:
            inside = np.minimum.reduce([px - x_lo, x_hi - px, py - y_lo, y_hi - py])  # pixels
        else:
            cx, cy = (x_lo + x_hi) / 2, (y_lo + y_hi) / 2
            rx, ry = max((x_hi - x_lo) / 2, 1), max((y_hi - y_lo) / 2, 1)
            inside = (1 - np.hypot((px - cx) / rx, (py - cy) / ry)) * min(rx, ry)
        # One-pixel soft edge, so the upsampled patch has a smooth outline.
        alpha = np.clip(inside + 0.5, 0, 1)[..., None] * rng.uniform(0.4, 1.0)
        color = _hsv_to_rgb(rng.uniform(0, 1, 1), rng.beta(1.2, 2.5, 1), rng.uniform(0.05, 1, 1))
        img = (1 - alpha) * img + alpha * color
    return (np.clip(img, 0, 1) * 255).astype(np.uint8)


def _checked(vertices, colors, K, R, t, size, num_vertices: int):
    """:meth:`Renderer.render`'s arrays as float32 meshes, float cameras and int sizes,
    checked against each other: (B, N, 3) twice, (B, V, 3, 3) twice, (B, V, 3), (B, V, 2)."""
    vertices = np.asarray(vertices, dtype=np.float32)
    colors = np.asarray(colors, dtype=np.float32)
    B, N = vertices.shape[:2]
    if vertices.shape != (B, num_vertices, 3):
        raise ValueError(f"vertices must have shape (B, {num_vertices}, 3), got {vertices.shape}")
    if colors.shape != vertices.shape:
        raise ValueError(f"colors must have shape {vertices.shape}, got {colors.shape}")
    K, R, t = np.asarray(K, float), np.asarray(R, float), np.asarray(t, float)
    size = np.asarray(size).astype(np.int64)
    V = K.shape[1] if K.ndim == 4 else -1
    for name, a, shape in (
        ("K", K, (B, V, 3, 3)),
        ("R", R, (B, V, 3, 3)),
        ("t", t, (B, V, 3)),
        ("size", size, (B, V, 2)),
    ):
        if a.shape != shape:
            raise ValueError(f"{name} must have shape {shape}, got {a.shape}")
    return vertices, colors, K, R, t, size


class Renderer:
    """Render bodies with one persistent headless OpenGL context.

    Args:
        faces: triangles shared by every mesh, shape (F, 3).
        num_vertices: vertices per mesh, N.
        samples: MSAA samples (0 or 1 for none); 4 gives smooth silhouettes but costs
            ~2-3x the time on software Mesa.
        background_scale: backgrounds are drawn at this fraction of the image size and
            upsampled by the GPU.
        backend: moderngl context backend, ``"egl"`` for headless.
    """

    def __init__(
        self,
        faces: np.ndarray,
        num_vertices: int,
        samples: int = 0,
        background_scale: float = 0.125,
        backend: str = "egl",
    ) -> None:
        import moderngl

        faces = np.asarray(faces)
        if faces.ndim != 2 or faces.shape[1] != 3:
            raise ValueError(f"faces must have shape (F, 3), got {faces.shape}")
        if faces.size and (faces.min() < 0 or faces.max() >= num_vertices):
            raise ValueError(f"faces index outside [0, {num_vertices})")
        self._mgl = moderngl
        self.ctx = moderngl.create_standalone_context(backend=backend)
        self.num_vertices = int(num_vertices)
        self.samples = int(samples) if samples and samples > 1 else 0
        self.background_scale = float(background_scale)
        self._prog = self.ctx.program(
            vertex_shader=_VERTEX_SHADER, fragment_shader=_FRAGMENT_SHADER
        )
        self._vbo = self.ctx.buffer(reserve=self.num_vertices * 9 * 4, dynamic=True)
        self._faces = faces.astype(np.int32)
        self._ibo = self.ctx.buffer(self._faces.tobytes())
        self._vao = self.ctx.vertex_array(
            self._prog, [(self._vbo, "3f 3f 3f", "in_pos", "in_normal", "in_color")], self._ibo
        )
        self._bg_prog = self.ctx.program(
            vertex_shader=_BACKGROUND_VERTEX, fragment_shader=_BACKGROUND_FRAGMENT
        )
        quad = np.array([-1, -1, 1, -1, -1, 1, 1, 1], dtype=np.float32)
        self._bg_vbo = self.ctx.buffer(quad.tobytes())
        self._bg_vao = self.ctx.vertex_array(self._bg_prog, [(self._bg_vbo, "2f", "in_xy")])
        self._targets: dict[tuple[int, int], tuple] = {}
        self._prog["body_alpha"].value = 1.0

    def close(self) -> None:
        """Release the OpenGL context."""
        for fbos in self._targets.values():
            for fbo in fbos:
                fbo.release()
        self._targets.clear()
        self.ctx.release()

    def __enter__(self) -> Renderer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _target(self, size: tuple[int, int]):
        """(draw framebuffer, framebuffer to read) for an image size, created once."""
        if size not in self._targets:
            ctx = self.ctx
            read = ctx.framebuffer(
                color_attachments=[ctx.renderbuffer(size, 4)],
                depth_attachment=ctx.depth_renderbuffer(size),
            )
            draw = read
            if self.samples:
                draw = ctx.framebuffer(
                    color_attachments=[ctx.renderbuffer(size, 4, samples=self.samples)],
                    depth_attachment=ctx.depth_renderbuffer(size, samples=self.samples),
                )
            self._targets[size] = (draw, read)
        return self._targets[size]

    def render(
        self,
        vertices: np.ndarray,
        colors: np.ndarray,
        K: np.ndarray,
        R: np.ndarray,
        t: np.ndarray,
        size: np.ndarray,
        lighting: list[Lighting] | None = None,
        backgrounds: bool = True,
        rng: np.random.Generator | int | None = None,
        return_masks: bool = False,
    ) -> list[np.ndarray] | tuple[list[np.ndarray], list[np.ndarray]]:
        """Render every body from each of its cameras.

        Args:
            vertices: shape (B, N, 3), world metres.
            colors: vertex RGB in [0, 1], shape (B, N, 3) (see :func:`random_outfits`).
            K: (B, V, 3, 3) pixels. R: (B, V, 3, 3). t: (B, V, 3) metres.
            size: image (width, height) per view, shape (B, V, 2), pixels.
            lighting: one :class:`Lighting` per body, or None for random lighting.
            backgrounds: draw procedural backgrounds; otherwise black.
            rng: numpy Generator or seed, for lighting and backgrounds.
            return_masks: also return the body silhouettes.

        Returns:
            B * V RGB images, body-major (image ``b * V + v``), each (H, W, 3) uint8 for its
            own size; with ``return_masks``, also B * V boolean masks (H, W).
        """
        vertices, colors, K, R, t, size = _checked(
            vertices, colors, K, R, t, size, self.num_vertices
        )
        B, V = K.shape[:2]
        rng = np.random.default_rng(rng)
        if lighting is None:
            lighting = [random_lighting(rng) for _ in range(B)]
        normals = vertex_normals(vertices, self._faces)
        images, masks = [], []
        for b in range(B):
            data = np.concatenate([vertices[b], normals[b], colors[b]], axis=-1)  # (N, 9)
            self._vbo.write(np.ascontiguousarray(data, dtype=np.float32).tobytes())
            self._set_lighting(lighting[b])
            for v in range(V):
                rgba = self._draw_view(K[b, v], R[b, v], t[b, v], size[b, v], backgrounds, rng)
                images.append(rgba[..., :3].copy())
                if return_masks:
                    masks.append(rgba[..., 3] > 127)
        return (images, masks) if return_masks else images

    def _draw_view(self, K, R, t, size, backgrounds: bool, rng: np.random.Generator):
        """The loaded body seen by one camera: RGBA, shape (H, W, 4) uint8, alpha = body."""
        self._begin_view(K, R, t, size, backgrounds, rng)
        self._vao.render(self._mgl.TRIANGLES)
        return self._read_view(size)

    def _begin_view(self, K, R, t, size, backgrounds: bool, rng: np.random.Generator) -> None:
        """Clear the view's target, draw its background, and set its camera."""
        ctx = self.ctx
        w, h = int(size[0]), int(size[1])
        draw, _ = self._target((w, h))
        draw.use()
        ctx.viewport = (0, 0, w, h)
        ctx.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        if backgrounds:
            self._draw_background(w, h, rng)
        ctx.enable(self._mgl.DEPTH_TEST)
        mvp = gl_projection(K, R, t, (w, h))
        self._prog["mvp"].write(mvp.T.astype(np.float32).tobytes())
        eye = -R.T @ t
        self._prog["eye"].value = tuple(float(x) for x in eye)

    def _read_view(self, size) -> np.ndarray:
        """The drawn view: RGBA, shape (H, W, 4) uint8."""
        w, h = int(size[0]), int(size[1])
        draw, read = self._target((w, h))
        if draw is not read:
            self.ctx.copy_framebuffer(read, draw)
        return np.frombuffer(read.read(components=4), np.uint8).reshape(h, w, 4)

    def render_scene(
        self,
        vertices: np.ndarray,
        colors: np.ndarray,
        K: np.ndarray,
        R: np.ndarray,
        t: np.ndarray,
        size: np.ndarray,
        present: np.ndarray | None = None,
        lighting: list[Lighting] | None = None,
        backgrounds: bool = True,
        rng: np.random.Generator | int | None = None,
    ) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """Render scenes of several bodies, which hide each other, from each scene's cameras.

        Args:
            vertices: shape (B, P, N, 3), world metres. colors: (B, P, N, 3) in [0, 1].
            K: (B, V, 3, 3) pixels. R: (B, V, 3, 3). t: (B, V, 3) metres.
            size: image (width, height) per view, shape (B, V, 2), pixels.
            present: (B, P) bool, the bodies each scene holds (None: all); at most 254.
            lighting: one :class:`Lighting` per scene, or None for random lighting.
            backgrounds: draw procedural backgrounds; otherwise black.
            rng: numpy Generator or seed, for lighting and backgrounds.

        Returns:
            B * V RGB images, scene-major (image ``b * V + v``), each (H, W, 3) uint8, and as
            many id masks (H, W) int16: the body each pixel shows, -1 for the background
            (exact without multisampling; with it, edge pixels may name a neighbour).
        """
        vertices, colors, present = _scene_arrays(vertices, colors, present)
        B, P, N = vertices.shape[:3]
        flat, flat_colors, K, R, t, size = _checked(
            vertices.reshape(B * P, N, 3), colors.reshape(B * P, N, 3), np.repeat(K, P, 0),
            np.repeat(R, P, 0), np.repeat(t, P, 0), np.repeat(size, P, 0), self.num_vertices,
        )  # fmt: skip
        V = K.shape[1]
        rng = np.random.default_rng(rng)
        if lighting is None:
            lighting = [random_lighting(rng) for _ in range(B)]
        normals = vertex_normals(flat, self._faces).reshape(B, P, N, 3)
        images, ids = [], []
        for b in range(B):
            data = [_vertex_data(vertices[b, p], normals[b, p], colors[b, p]) for p in range(P)]
            self._set_lighting(lighting[b])
            for v in range(V):
                i = b * P  # the cameras of scene b (repeated per body above)
                self._begin_view(K[i, v], R[i, v], t[i, v], size[i, v], backgrounds, rng)
                for p in np.flatnonzero(present[b]):
                    self._vbo.write(data[p])
                    self._prog["body_alpha"].value = (p + 1) / 255.0
                    self._vao.render(self._mgl.TRIANGLES)
                rgba = self._read_view(size[i, v])
                images.append(rgba[..., :3].copy())
                ids.append(rgba[..., 3].astype(np.int16) - 1)
        self._prog["body_alpha"].value = 1.0
        return images, ids

    def _set_lighting(self, light: Lighting) -> None:
        dirs = np.asarray(light.directions, float)
        dirs = dirs / np.linalg.norm(dirs, axis=-1, keepdims=True)
        self._prog["light_dir"].write(dirs.astype(np.float32).tobytes())
        self._prog["light_color"].write(np.asarray(light.colors, np.float32).tobytes())
        self._prog["ambient"].value = tuple(float(x) for x in light.ambient)
        self._prog["specular"].value = float(light.specular)
        self._prog["shininess"].value = float(light.shininess)

    def _draw_background(self, w: int, h: int, rng: np.random.Generator) -> None:
        bw = max(2, round(w * self.background_scale))
        bh = max(2, round(h * self.background_scale))
        img = random_background(bw, bh, rng)
        tex = self.ctx.texture((bw, bh), 3, np.ascontiguousarray(img).tobytes())
        tex.filter = (self._mgl.LINEAR, self._mgl.LINEAR)
        tex.repeat_x = tex.repeat_y = False
        tex.use(0)
        self._bg_prog["image"].value = 0
        self.ctx.disable(self._mgl.DEPTH_TEST)
        self._bg_vao.render(self._mgl.TRIANGLE_STRIP)
        tex.release()


def _scene_arrays(vertices, colors, present):
    """:meth:`Renderer.render_scene`'s bodies, checked: vertices and colours (B, P, N, 3)
    float32, and which bodies each scene holds (B, P) bool."""
    vertices = np.asarray(vertices, dtype=np.float32)
    colors = np.asarray(colors, dtype=np.float32)
    if vertices.ndim != 4 or colors.shape != vertices.shape:
        raise ValueError(
            f"vertices and colors must have one shape (B, P, N, 3), got {vertices.shape} "
            f"and {colors.shape}"
        )
    B, P = vertices.shape[:2]
    present = np.ones((B, P), bool) if present is None else np.asarray(present, bool)
    if present.shape != (B, P) or P > 254:
        raise ValueError(f"present must have shape ({B}, {P}) with P <= 254")
    return vertices, colors, present


def _vertex_data(vertices, normals, colors) -> bytes:
    """One body's vertex buffer: position, normal, colour per vertex, (N, 9) float32."""
    return np.ascontiguousarray(
        np.concatenate([vertices, normals, colors], axis=-1), dtype=np.float32
    ).tobytes()
