"""The top-down render of a scene: lighting, the terrain layer (``terrain``), meshes and their shadows
(``objects``) composited into one aerial photograph; whole scenes, scene files and single-mesh views.

Terrain is shaded with vectorised numpy/OpenCV (class textures with procedural noise, hillshade,
water tinted by depth with ripples and sun glint); placed meshes are ray-cast with embree (through
``trimesh.ray.ray_pyembree``), only where objects and their shadows are. Frames follow DESIGN.md §2:
x east = image right, y north = image up, yaw counter-clockwise from +x.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import cv2
import numpy as np

from ..classes import N_CLASSES, WATER
from ..errors import InputError
from ..rng import stage_rng
from .objects import (
    PixelGrid,
    composite_instances,
    heightfield_shadow,
    sun_vector,
)
from .terrain import (
    NoiseBank,
    hillshade,
    resample_classes,
    resample_height,
    srgb,
    terrain_albedo,
    water_body,
    water_surface,
)

F32 = np.float32
MAX_PIXELS = 6144 * 6144  # ~240 bytes per pixel at peak: larger renders must be tiled by the caller

if TYPE_CHECKING:  # trimesh takes ~1 s to import: only the functions that touch meshes load it
    import trimesh


@dataclass(frozen=True)
class Lighting:
    sun_azimuth_deg: float = 135.0  # compass-free: CCW from +x (scene frame)
    sun_elevation_deg: float = 55.0
    ambient: float = 0.35
    shadow_softness: float = 0.6
    water_shallow_rgb: tuple[int, int, int] = (60, 150, 150)
    water_deep_rgb: tuple[int, int, int] = (10, 50, 80)
    turbidity: float = 0.4
    glint: float = 0.3
    exposure: float = 1.0
    haze: float = 0.0  # 0 clear .. ~0.3 hazy: blends towards a bright blue-grey veil


@dataclass(frozen=True, eq=False)
class MeshInstance:
    mesh: trimesh.Trimesh  # scene frame: z-up, metres, forward +x, with face_colors
    x_m: float
    y_m: float
    z_m: float
    yaw_deg: float
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    tint: tuple[float, float, float] | None = None  # optional colour jitter multiplier


def random_lighting(rng: np.random.Generator) -> Lighting:
    """Plausible variety: time of day (sun height and direction), water colour and clarity, haze."""
    elev = float(rng.choice([rng.uniform(25, 45), rng.uniform(45, 75)], p=[0.35, 0.65]))
    kind = rng.choice(["tropical", "coastal", "green", "murky"], p=[0.2, 0.4, 0.25, 0.15])
    shallow = {
        "tropical": (70, 175, 170),
        "coastal": (60, 140, 140),
        "green": (70, 125, 95),
        "murky": (105, 110, 80),
    }[kind]
    deep = {"tropical": (10, 70, 110), "coastal": (12, 48, 72), "green": (18, 55, 52), "murky": (40, 52, 45)}[
        kind
    ]
    turb = {"tropical": (0.05, 0.3), "coastal": (0.2, 0.6), "green": (0.35, 0.7), "murky": (0.6, 0.95)}[kind]
    jitter = rng.integers(-12, 13, 3)
    return Lighting(
        sun_azimuth_deg=float(rng.uniform(-180, 180)),
        sun_elevation_deg=elev,
        ambient=float(rng.uniform(0.28, 0.45)),
        shadow_softness=float(rng.uniform(0.2, 1.0)),
        water_shallow_rgb=tuple(int(np.clip(c + j, 0, 255)) for c, j in zip(shallow, jitter)),
        water_deep_rgb=tuple(int(np.clip(c + j // 2, 0, 255)) for c, j in zip(deep, jitter)),
        turbidity=float(rng.uniform(*turb)),
        glint=float(rng.uniform(0.1, 0.6)),
        exposure=float(rng.uniform(0.9, 1.12)),
        haze=float(rng.choice([0.0, rng.uniform(0.03, 0.2)], p=[0.6, 0.4])),
    )


def standard_view_lightings() -> tuple[Lighting, Lighting, Lighting]:
    """The asset library's 3 fixed lightings: morning low sun, noon high sun, soft hazy afternoon."""
    return (
        Lighting(sun_azimuth_deg=200.0, sun_elevation_deg=35.0, ambient=0.33, shadow_softness=0.4),
        Lighting(sun_azimuth_deg=135.0, sun_elevation_deg=70.0, ambient=0.35, shadow_softness=0.5),
        Lighting(
            sun_azimuth_deg=30.0,
            sun_elevation_deg=50.0,
            ambient=0.5,
            shadow_softness=1.0,
            haze=0.08,
            exposure=1.05,
        ),
    )


# ---------------------------------------------------------------- shading core


def _sun_colours(lighting: Lighting):
    k = float(np.clip(np.sin(np.deg2rad(lighting.sun_elevation_deg)) / 0.7, 0.0, 1.0))
    sun_rgb = np.array([1.0, 0.92 + 0.08 * k, 0.80 + 0.20 * k], F32)  # low sun is warmer
    sky_rgb = np.array([0.88, 0.95, 1.10], F32)  # shadows are lit by the blue sky
    return sun_rgb, sky_rgb


def _col(v) -> np.ndarray:
    """A per-channel constant shaped to broadcast over planar (3, ...) arrays."""
    return np.asarray(v, F32).reshape(3, *([1] * 1))


def _finish(img: np.ndarray, lighting: Lighting, grid: PixelGrid, noise: NoiseBank) -> np.ndarray:
    """Planar float image (3, H, W) → haze, exposure, a gentle filmic shoulder, optics blur and sensor
    noise → (H, W, 3) uint8. Works in place."""
    if lighting.haze > 0:
        img *= F32(1.0 - lighting.haze)
        img += (np.array([0.78, 0.82, 0.88], F32) * F32(lighting.haze))[:, None, None]
    img *= F32(lighting.exposure)
    # soft shoulder x / (1 + 0.22 x): bright glint and white decks do not clip hard
    den = img * F32(0.22)
    den += F32(1.0)
    img /= den
    del den
    sensor = F32(0.008 / 1.22) * noise.grain("sensor")
    chans = []
    for ch in range(3):
        c = cv2.GaussianBlur(img[ch], (0, 0), 0.55)
        c += sensor
        chans.append(cv2.convertScaleAbs(c, alpha=255.0 * 1.22, beta=0.5))
    return cv2.merge(chans)


@dataclass(eq=False)
class _Shaded:
    """The background fully sunlit (``lit``) plus what is needed to shade any pixel as fully in an
    object's shadow: the final colour is linear in the shadow fraction, so objects only need the
    shadowed colour where their shadows fall. Images are planar (3, H, W); per-pixel lists (3, N)."""

    lit: np.ndarray  # (3, H, W)
    base: np.ndarray  # (3, H, W) albedo × relief
    ambient: np.ndarray  # (3, 1) sky light in shadow, normalised
    water_pos: np.ndarray  # (H*W,) int32: index into the water arrays, -1 on land
    t3: np.ndarray | None = None  # (3, N) seabed transmittance per channel
    body: np.ndarray | None = None  # (3, N)
    refl: np.ndarray | None = None  # (3, N)
    foam: np.ndarray | None = None  # (1, N)

    def dark_at(self, idx: np.ndarray) -> np.ndarray:
        out = self.base.reshape(3, -1)[:, idx] * self.ambient
        if self.t3 is not None:
            wp = self.water_pos[idx]
            w = np.flatnonzero(wp >= 0)
            j = wp[w]
            t3 = self.t3[:, j]
            c = out[:, w] * t3 + self.body[:, j] * F32(0.35) * (1.0 - t3) + self.refl[:, j]
            if self.foam is not None:
                fm = self.foam[:, j]
                c = c * (1 - fm) + _col([0.5, 0.52, 0.53]) * fm
            out[:, w] = c
        return out


def _background(
    grid: PixelGrid, albedo, relief, ndl, water, depth, lighting: Lighting, seed: int, noise: NoiseBank
) -> _Shaded:
    """Terrain/seabed (planar albedo (3, H, W)) lit by sun and sky with hillshade ``ndl``, water over it."""
    sun = sun_vector(lighting.sun_azimuth_deg, lighting.sun_elevation_deg)
    sun_rgb, sky_rgb = _sun_colours(lighting)
    amb = float(np.clip(lighting.ambient, 0.0, 1.0))
    ref = amb + (1 - amb) * (0.5 * sun[2] + 0.5 * 0.82)  # partial auto-exposure for sun height
    base = albedo
    base *= relief
    ambient = _col(amb * sky_rgb / ref)
    direct = (1 - amb) / ref * sun_rgb
    lit = np.empty_like(base)
    for ch in range(3):
        lit[ch] = ndl * F32(direct[ch])
        lit[ch] += ambient[ch, 0]
        lit[ch] *= base[ch]
    wf = water.reshape(-1)
    widx = np.flatnonzero(wf)
    water_pos = np.full(wf.shape, -1, np.int32)
    sh = _Shaded(lit, base, ambient, water_pos)
    if len(widx):
        water_pos[widx] = np.arange(len(widx), dtype=np.int32)
        body, trans = water_body(depth.reshape(-1)[widx], widx, lighting, noise)
        sky_refl, glint = water_surface(widx, grid, noise, lighting, sun, seed)
        # the seabed is seen through the column: red goes first, so shallow water turns turquoise
        absorb = _col([0.55, 0.85, 0.95])
        t3 = trans[None] * (absorb + (1 - absorb) * trans[None])
        body *= F32(0.8 + 0.2 * sun[2] / 0.82)
        refl = _col([0.55, 0.65, 0.75]) * (0.025 + sky_refl)[None]
        litf = lit.reshape(3, -1)
        w = litf[:, widx] * t3 + body * (1.0 - t3) + refl + glint[None] * _col(sun_rgb)
        foam = None
        if len(widx) < len(wf):  # thin foam / lapping line where water meets land
            dist = cv2.distanceTransform(water.astype(np.uint8), cv2.DIST_L2, 3).reshape(-1)[widx] * F32(
                grid.gsd
            )
            near = np.flatnonzero(dist < 2.0)
            if len(near):
                foam = np.zeros((1, len(widx)), F32)
                fn = np.exp(-dist[near] / F32(0.35)) * np.clip(
                    0.6 + 0.6 * noise.field("foam", 0.8).reshape(-1)[widx[near]], 0, 1
                )
                foam[0, near] = fn * F32(np.clip(1.0 - lighting.turbidity * 0.5, 0.3, 1.0) * 0.5)
                w = w * (1 - foam) + _col([0.85, 0.88, 0.88]) * foam
        litf[:, widx] = w
        sh.t3, sh.body, sh.refl, sh.foam = t3, body, refl, foam
    return sh


def _objects_and_shadows(
    instances, grid: PixelGrid, floor_z, surface_z, lighting: Lighting, shadows: bool = True
):
    """Composite the instances, then their soft shadows (and the terrain's) and the contact darkening.
    Independent of the terrain colours, so it runs beside the terrain shading. Returns (obj, sh, ao)."""
    obj = composite_instances(instances, grid, floor_z, surface_z)
    sh = ao = None
    if obj.n_instances or shadows:
        sun = sun_vector(lighting.sun_azimuth_deg, lighting.sun_elevation_deg)
        hard = heightfield_shadow(obj.height, grid, sun)
        sig_px = max((0.04 + 0.3 * float(lighting.shadow_softness)) / grid.gsd, 0.3)
        sh = cv2.GaussianBlur(hard, (0, 0), sig_px)
    if obj.n_instances:  # contact darkening (ambient occlusion) around objects on the ground or afloat
        ao = cv2.GaussianBlur(obj.alpha, (0, 0), max(0.5 / grid.gsd, 0.7))
        ao = 1.0 - 0.3 * ao * (1.0 - obj.alpha)
    return obj, sh, ao


def _objects_over(
    shaded: _Shaded,
    water,
    layers,
    lighting: Lighting,
    water_level: float = 0.0,
) -> np.ndarray:
    """Instances and soft cast shadows (``layers`` from ``_objects_and_shadows``) over the shaded
    background. Returns the planar float image (3, H, W)."""
    obj, sh, ao = layers
    sun = sun_vector(lighting.sun_azimuth_deg, lighting.sun_elevation_deg)
    sun_rgb, sky_rgb = _sun_colours(lighting)
    amb = float(np.clip(lighting.ambient, 0.0, 1.0))
    ref = amb + (1 - amb) * (0.5 * sun[2] + 0.5 * 0.82)
    img = shaded.lit.copy()
    if sh is None:
        return img
    if ao is not None:
        touched = np.flatnonzero((sh > 4e-3) | (ao < 0.995))  # below ~1 grey level: skip
    else:
        touched = np.flatnonzero(sh > 4e-3)
    imf = img.reshape(3, -1)
    if len(touched):
        s = sh.reshape(-1)[touched][None]
        v = imf[:, touched] * (1 - s) + shaded.dark_at(touched) * s
        if ao is not None:
            v *= ao.reshape(-1)[touched][None]
        imf[:, touched] = v
    idx = np.flatnonzero(obj.alpha > 0)
    if len(idx):
        n = obj.normal.reshape(3, -1)[:, idx]
        sv = sun.astype(F32)
        ndl_o = np.clip(n[0] * sv[0] + n[1] * sv[1] + n[2] * sv[2], 0.0, 1.0)
        l_o = 1.0 - sh.reshape(-1)[idx]
        c = obj.rgb.reshape(3, -1)[:, idx]
        col = c * (
            _col(amb * sky_rgb) * (0.6 + 0.4 * n[2:3]) + _col((1 - amb) * sun_rgb) * (ndl_o * l_o)[None]
        )
        col /= F32(ref)
        hv = (sun + np.array([0, 0, 1.0])).astype(F32)
        hv /= np.linalg.norm(hv)
        spec = np.clip(n[0] * hv[0] + n[1] * hv[1] + n[2] * hv[2], 0, 1) ** 40 * F32(0.25) * l_o
        col += spec[None] * _col(sun_rgb)
        bg = imf[:, idx]
        zo = obj.z.reshape(-1)[idx]
        under = np.flatnonzero(water.reshape(-1)[idx] & (zo < water_level - 0.02))
        if len(under):
            dz = water_level - zo[under]
            vis = 0.4 + 3.5 * (1.0 - float(np.clip(lighting.turbidity, 0, 1))) ** 1.5
            t = np.exp(-dz / vis)[None]
            col[:, under] = col[:, under] * t + bg[:, under] * (1 - t)
        a = obj.alpha.reshape(-1)[idx][None]
        imf[:, idx] = col * a + bg * (1 - a)
    return img


_VIEW_BG: dict = {}  # (size, gsd, lighting, background, seed) -> (lit, dark): the library renders many views


# ---------------------------------------------------------------- public API


def _check_gsd(gsd_m: float) -> float:
    if (
        isinstance(gsd_m, bool)
        or not isinstance(gsd_m, (int, float, np.integer, np.floating))
        or not np.isfinite(gsd_m)
        or gsd_m <= 0
    ):
        raise InputError(f"gsd_m = {gsd_m!r} must be a positive number of metres per pixel (e.g. --gsd 0.1)")
    return float(gsd_m)


@dataclass
class TerrainLayer:
    """The shaded terrain of a top-down render, before objects: it depends only on the terrain rasters, so
    ``generate`` renders it for the report while later stages run (``render_topdown(terrain=...)``)."""

    grid: PixelGrid
    noise: NoiseBank
    z: np.ndarray
    surface_z: np.ndarray
    water: np.ndarray
    shaded: np.ndarray
    water_level_m: float
    key: tuple  # what it was rendered from: (shape of the rasters, extent, gsd, lighting, seed, water level)


def _layer_key(classes, extent_m, gsd, lighting, seed, water_level_m) -> tuple:
    return (tuple(np.shape(classes)), tuple(float(v) for v in extent_m), float(gsd), lighting, int(seed),
            float(water_level_m))


def render_terrain_layer(
    classes: np.ndarray,
    height: np.ndarray,
    extent_m: tuple[float, float],
    gsd_m: float,
    lighting: Lighting = Lighting(),
    seed: int = 0,
    water_level_m: float = 0.0,
    instances: Sequence[MeshInstance] | None = None,
) -> TerrainLayer | tuple[TerrainLayer, list]:
    """The shaded terrain seen from straight above (see ``render_topdown``). With ``instances``, their
    objects and shadows are rendered beside it (a second thread) and returned with it."""
    gsd = _check_gsd(gsd_m)
    classes = np.asarray(classes)
    height = np.asarray(height)
    if classes.ndim != 2 or height.ndim != 2 or classes.shape != height.shape:
        raise InputError(
            f"classes {classes.shape} and height {height.shape} must be 2-D arrays of the same shape"
        )
    if classes.size == 0:
        raise InputError("classes/height are empty; the scene grid needs at least one pixel")
    if classes.dtype != np.uint8:
        if not np.issubdtype(classes.dtype, np.integer):
            raise InputError(f"classes dtype {classes.dtype} must be integer class ids 0..{N_CLASSES - 1}")
        classes = classes.astype(np.uint8)
    if int(classes.max()) >= N_CLASSES:
        raise InputError(f"class id {int(classes.max())} is not one of 0..{N_CLASSES - 1}")
    try:
        w_m, h_m = (float(v) for v in extent_m)
    except (TypeError, ValueError) as exc:
        raise InputError(f"extent_m = {extent_m!r} must be (width, height) in metres") from exc
    if not (w_m > 0 and h_m > 0 and np.isfinite(w_m) and np.isfinite(h_m)):
        raise InputError(f"extent_m = {extent_m!r} must be two positive finite numbers (metres)")
    W, H = max(1, round(w_m / gsd)), max(1, round(h_m / gsd))
    if W * H > MAX_PIXELS:
        raise InputError(
            f"a {W}x{H} px render at gsd {gsd} m is too large (> {MAX_PIXELS} px); use a coarser --gsd"
        )
    hgt = np.nan_to_num(height.astype(F32), nan=0.0)
    grid = PixelGrid((w_m, h_m), W, H)
    noise = NoiseBank(grid, seed)
    cls = resample_classes(classes, grid, noise)
    z = resample_height(hgt, grid)
    wl = float(water_level_m)
    water = (cls == WATER) | (z < wl)
    depth = np.where(water, np.maximum(wl - z, np.where(cls == WATER, 0.15, 0.02)), 0.0).astype(F32)
    surface_z = np.where(water, F32(wl), z).astype(F32)
    sun = sun_vector(lighting.sun_azimuth_deg, lighting.sun_elevation_deg)
    # the instance compositing loop is mostly Python (holds the GIL) while terrain shading is mostly large
    # numpy/OpenCV operations (release it): running both at once keeps two cores busy
    with ThreadPoolExecutor(max_workers=1) as pool:
        fut = (pool.submit(_objects_and_shadows, list(instances), grid, z, surface_z, lighting)
               if instances is not None else None)
        albedo, relief = terrain_albedo(cls, grid, noise, seed, sun, water)
        ndl = hillshade(z, grid, sun)
        shaded = _background(grid, albedo, relief, ndl, water, depth, lighting, seed, noise)
        del albedo, relief, ndl
        layers = fut.result() if fut is not None else None
    layer = TerrainLayer(grid, noise, z, surface_z, water, shaded, wl,
                         _layer_key(classes, (w_m, h_m), gsd, lighting, seed, wl))
    return layer if instances is None else (layer, layers)


def render_topdown(
    classes: np.ndarray,
    height: np.ndarray,
    extent_m: tuple[float, float],
    instances: Sequence[MeshInstance],
    gsd_m: float,
    lighting: Lighting = Lighting(),
    seed: int = 0,
    water_level_m: float = 0.0,
    terrain: TerrainLayer | None = None,
) -> np.ndarray:
    """Render terrain + instances seen from straight above. ``classes`` (H, W) uint8 ids and ``height``
    (H, W) float32 metres on the scene grid covering ``extent_m`` centred on the origin. Returns an RGB
    uint8 image of round(extent_h / gsd) rows × round(extent_w / gsd) columns. ``terrain``: the
    ``render_terrain_layer`` of the same arguments, already rendered (one of others is ignored)."""
    key = _layer_key(classes, extent_m, _check_gsd(gsd_m), lighting, seed, water_level_m) \
        if terrain is not None else None
    if terrain is not None and terrain.key == key:
        layer = terrain
        layers = _objects_and_shadows(list(instances), layer.grid, layer.z, layer.surface_z, lighting)
    else:
        layer, layers = render_terrain_layer(classes, height, extent_m, gsd_m, lighting, seed, water_level_m,
                                             instances=instances)
    img = _objects_over(layer.shaded, layer.water, layers, lighting, water_level=layer.water_level_m)
    return _finish(img, lighting, layer.grid, layer.noise)


def render_scene(
    scene,
    mesh_for: Callable[[str], trimesh.Trimesh],
    gsd_m: float,
    lighting: Lighting = Lighting(),
    seed: int = 0,
    terrain: TerrainLayer | None = None,
) -> np.ndarray:
    """Render a ``coastforge.scene.Scene``: terrain rasters, objects and vegetation instances.
    ``mesh_for(asset_id)`` returns the asset's mesh (called once per asset id); ``terrain``: its
    ``scene_terrain_layer``, when already rendered."""
    if scene.classes is None or scene.height is None:
        raise InputError(
            f"scene {scene.name!r} has no terrain rasters (classes/height); load it with rasters=True"
        )
    cache: dict[str, trimesh.Trimesh] = {}

    def get(asset_id: str) -> trimesh.Trimesh:
        if asset_id not in cache:
            cache[asset_id] = mesh_for(asset_id)
        return cache[asset_id]

    instances = []
    for o in scene.objects:
        tint = o.attrs.get("tint") if isinstance(o.attrs, dict) else None
        tint = tuple(float(t) for t in tint) if isinstance(tint, (list, tuple)) and len(tint) == 3 else None
        instances.append(MeshInstance(get(o.asset_id), o.x_m, o.y_m, o.z_m, o.yaw_deg, tuple(o.scale), tint))
    veg = scene.vegetation
    if veg is not None and len(veg):
        rng = stage_rng(seed, "render", "vegetation_tint")
        tints = rng.uniform(0.85, 1.12, (len(veg), 3)) * rng.uniform(0.9, 1.1, (len(veg), 1))
        for i in range(len(veg)):
            s = float(veg.scale[i])
            instances.append(
                MeshInstance(
                    get(str(veg.asset_id[i])),
                    float(veg.x_m[i]),
                    float(veg.y_m[i]),
                    float(veg.z_m[i]),
                    float(veg.yaw_deg[i]),
                    (s, s, s),
                    tuple(float(t) for t in tints[i]),
                )
            )
    return render_topdown(
        scene.classes, scene.height, scene.extent_m, instances, gsd_m, lighting, seed, scene.water_level_m,
        terrain=terrain,
    )


def scene_terrain_layer(classes: np.ndarray, height: np.ndarray, extent_m, water_level_m: float, gsd_m: float,
                        lighting: Lighting = Lighting(), seed: int = 0) -> TerrainLayer:
    """``render_scene``'s terrain layer of a scene with these rasters, rendered ahead of its objects."""
    return render_terrain_layer(classes, height, extent_m, gsd_m, lighting, seed, water_level_m)


def render_mesh_view(
    mesh: trimesh.Trimesh,
    gsd_m: float,
    size_px: int,
    lighting: Lighting,
    background: str,
    yaw_deg: float = 0.0,
    seed: int = 0,
    centre_xy: tuple[float, float] | None = None,
) -> np.ndarray:
    """One asset centred (its footprint's bounding-box centre at the image centre), seen from above on a
    'water' (dark, slightly textured) or 'ground' (light grey/beige) background. (size, size, 3) uint8.
    ``centre_xy``: the mesh point (x, y) to centre instead (one object of a mesh holding several)."""
    gsd = _check_gsd(gsd_m)
    if background not in ("water", "ground"):
        raise InputError(f"background = {background!r} must be 'water' or 'ground'")
    if not isinstance(size_px, (int, np.integer)) or not 8 <= size_px <= 8192:
        raise InputError(f"size_px = {size_px!r} must be an integer in 8..8192")
    import trimesh

    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise InputError(f"mesh {mesh!r} must be a non-empty trimesh.Trimesh")
    n = size_px
    ext = size_px * gsd
    grid = PixelGrid((ext, ext), n, n)
    noise = NoiseBank(grid, seed)
    b = mesh.bounds
    cx, cy = (0.5 * (b[0, 0] + b[1, 0]), 0.5 * (b[0, 1] + b[1, 1])) if centre_xy is None else centre_xy
    r = np.deg2rad(yaw_deg)
    # rotate the centring offset too, so the footprint centre lands on the image centre at any yaw
    ox, oy = -(np.cos(r) * cx - np.sin(r) * cy), -(np.sin(r) * cx + np.cos(r) * cy)
    inst = MeshInstance(mesh, float(ox), float(oy), 0.0, float(yaw_deg))
    shape = (n, n)
    key = (n, gsd, lighting, background, seed)
    bg = _VIEW_BG.get(key)
    if bg is None:
        sun = sun_vector(lighting.sun_azimuth_deg, lighting.sun_elevation_deg)
        ndl = np.full(shape, sun[2], F32)
        if background == "water":
            water = np.ones(shape, bool)
            depth = np.full(shape, 8.0, F32)
            albedo = np.broadcast_to(srgb((120, 115, 95))[:, None, None], (3,) + shape).astype(F32)
        else:
            water = np.zeros(shape, bool)
            depth = np.zeros(shape, F32)
            tone = (
                1.0
                + 0.03 * noise.field("bg1", 3.0)
                + 0.025 * noise.field("bg2", 0.6)
                + 0.02 * noise.grain("bg")
            )
            albedo = srgb((188, 184, 172))[:, None, None] * tone[None]
        shaded = _background(grid, albedo, np.ones(shape, F32), ndl, water, depth, lighting, seed, noise)
        bg = (shaded, water, noise)  # the noise bank keeps its grain field for the sensor noise
        if len(_VIEW_BG) >= 24:
            _VIEW_BG.clear()  # simple bound; the library renders views grouped by lighting and background
        _VIEW_BG[key] = bg
    shaded, water, noise = bg
    floor = np.full(shape, -50.0 if background == "water" else float(b[0, 2]), F32)
    surface_z = np.full(shape, 0.0 if background == "water" else float(b[0, 2]), F32)
    layers = _objects_and_shadows([inst], grid, floor, surface_z, lighting, shadows=False)
    img = _objects_over(shaded, water, layers, lighting)
    return _finish(img, lighting, grid, noise)


def kit_mesh_lookup() -> Callable[[str], trimesh.Trimesh]:
    """``mesh_for`` backed by the installed starter kit (``coastforge.assets.kit``)."""
    from ..assets.kit import load_kit_mesh

    return load_kit_mesh


def render_scene_file(
    scene_path,
    gsd_m: float,
    out_path,
    seed: int = 0,
    overwrite: bool = False,
    lighting: Lighting | None = None,
    mesh_for: Callable[[str], trimesh.Trimesh] | None = None,
):
    """Load a scene (folder or scene/truth JSON), render it from above and write a PNG or JPEG atomically.
    ``lighting`` None: the default lighting. Returns the written path."""
    from pathlib import Path

    from ..fsio import check_writable_file, write_jpeg, write_png
    from ..scene import load_scene

    out = Path(out_path)
    suffix = out.suffix.lower()
    if suffix not in (".png", ".jpg", ".jpeg"):
        raise InputError(f"--out {out} must end in .png, .jpg or .jpeg")
    check_writable_file(out, overwrite)
    _check_gsd(gsd_m)
    scene = load_scene(scene_path)
    img = render_scene(scene, mesh_for or kit_mesh_lookup(), gsd_m, lighting or Lighting(), seed)
    return write_png(out, img) if suffix == ".png" else write_jpeg(out, img)
