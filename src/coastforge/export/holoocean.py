"""HoloOcean scenario (DESIGN.md §6) for the level built from the ue5 bundle.

``{World}-{Scenario}.json`` goes into the user's package folder (``worlds/{package}``), and the world
entry (``config_world_entry.json``) into that package's ``config.json`` ``worlds`` list — without it
``holoocean.make`` fails. HoloOcean uses the scene frame (metres, x east, y north, z up).

Agents: a HoveringAUV in water deep enough for it (between the surface and the seabed with margins,
clear of every object) with imaging sonar, DVL, IMU, depth, camera, semantic segmentation camera and pose
sensors; a SurfaceVessel on open water clear of objects with GPS, IMU, a semantic lidar and a camera.

Sensor rates: HoloOcean's client samples a sensor every ``ticks_per_sec // Hz`` ticks; it refuses a rate above
``ticks_per_sec`` (ValueError) and silently rounds one that does not divide it (a 20 Hz DVL at 30 ticks per
second runs at 30 Hz). So every rate here is the divisor of ``ticks_per_sec`` nearest the wanted one, and the
scenario is checked before it is written. Source: the client's ``HoloOceanEnvironment._load_scenario``
(``client/src/holoocean/environments.py`` of the HoloOcean client, e.g. github.com/wellscrosby/MRGHoloOcean).
The semantic sensors (``SemanticSegmentationCamera``, ``RaycastSemanticLidar``) are documented in
byu-holoocean/holoocean-docs ``develop/_sources/sensors/sensors/`` (HoloOcean after 2.2.0); they report the
labels the ue5 bundle gives every actor (its first tag, see ``labels.py``).
"""

from __future__ import annotations

import json

import numpy as np

from .. import __version__
from ..errors import InputError
from . import safe_name
from .terrain_mesh import resample_height, sample_class, vertex_grid
from ..classes import WATER

AUV_DEPTH_MARGIN_M = 1.0  # clearance below the surface and above the seabed
AUV_MIN_WATER_M = 2.5  # water depth needed to place the AUV
VESSEL_MIN_WATER_M = 1.0
SCENARIO_NAME = "Survey"
AGENT_TYPES = ("HoveringAUV", "SurfaceVessel", "TorpedoAUV", "BlueROV2")
# sockets per agent, from HoloOcean's agent pages (agents/hovering-auv-agent, agents/surface-vessel-agent)
AGENT_SOCKETS = {
    "HoveringAUV": ("COM", "DVLSocket", "IMUSocket", "DepthSocket", "SonarSocket", "CameraRightSocket",
                    "CameraLeftSocket", "Origin", "Viewport"),
    "SurfaceVessel": ("Payload", "Platform", "Viewport"),
}
SENSOR_TYPES = ("ImagingSonar", "SidescanSonar", "ProfilingSonar", "DVLSensor", "IMUSensor", "DepthSensor",
                "GPSSensor", "PoseSensor", "RGBCamera", "RaycastSemanticLidar", "SemanticSegmentationCamera")


def sensor_hz(wanted: float, ticks: int) -> int:
    """The divisor of ``ticks`` nearest ``wanted`` (the faster one on a tie): a rate HoloOcean runs exactly."""
    divisors = [d for d in range(1, ticks + 1) if ticks % d == 0]
    return min(divisors, key=lambda d: (abs(d - wanted), -d))


def check_rates(scenario: dict) -> None:
    """Every sensor's Hz divides ticks_per_sec (what HoloOcean's client needs to run it at that rate)."""
    ticks = int(scenario["ticks_per_sec"])
    for agent in scenario["agents"]:
        for sen in agent["sensors"]:
            hz = sen.get("Hz", ticks)
            if not (isinstance(hz, int) and 0 < hz <= ticks and ticks % hz == 0):
                raise InputError(f"sensor {sen.get('sensor_name')} of {agent['agent_name']} runs at {hz} Hz, which "
                                 f"does not divide export.ticks_per_sec = {ticks}; HoloOcean would round it")


def _sensor(kind: str, name: str, socket: str, hz: int, config: dict | None = None, rotation=None) -> dict:
    s = {"sensor_type": kind, "sensor_name": name, "socket": socket, "Hz": int(hz),
         "location": [0.0, 0.0, 0.0], "rotation": list(rotation or [0.0, 0.0, 0.0])}
    if config:
        s["configuration"] = config
    return s


def auv_sensors(ticks: int, sonar_range_m: float) -> list[dict]:
    hz = lambda f: sensor_hz(f, ticks)  # noqa: E731  (a divisor of ticks_per_sec)
    return [
        _sensor("ImagingSonar", "ImagingSonar", "SonarSocket", hz(10), {
            "RangeBins": 512, "AzimuthBins": 512, "RangeMin": 0.5, "RangeMax": float(sonar_range_m),
            "InitOctreeRange": float(sonar_range_m + 10.0), "Elevation": 20, "Azimuth": 120,
            "AzimuthStreaks": -1, "ScaleNoise": True, "AddSigma": 0.15, "MultSigma": 0.2, "RangeSigma": 0.1,
            "MultiPath": True}),
        _sensor("DVLSensor", "DVLSensor", "DVLSocket", hz(20), {
            "Elevation": 22.5, "VelSigma": 0.02626, "ReturnRange": True, "MaxRange": 50, "RangeSigma": 0.1}),
        _sensor("IMUSensor", "IMUSensor", "IMUSocket", hz(ticks), {
            "AccelSigma": 0.00277, "AngVelSigma": 0.00123, "AccelBiasSigma": 0.00141, "AngVelBiasSigma": 0.00388,
            "ReturnBias": True}),
        _sensor("DepthSensor", "DepthSensor", "DepthSocket", hz(ticks), {"Sigma": 0.255}),
        _sensor("RGBCamera", "LeftCamera", "CameraLeftSocket", hz(10), {"CaptureWidth": 512, "CaptureHeight": 512}),
        # labels per pixel: the stencil values of the actors' first tags (instances.json holoocean_id)
        _sensor("SemanticSegmentationCamera", "SemanticCamera", "CameraRightSocket", hz(10),
                {"CaptureWidth": 512, "CaptureHeight": 512}),
        _sensor("PoseSensor", "PoseSensor", "IMUSocket", hz(ticks)),
    ]


def vessel_sensors(ticks: int) -> list[dict]:
    """On the SurfaceVessel's ``Platform`` socket (its sockets are Payload, Platform, Viewport)."""
    hz = lambda f: sensor_hz(f, ticks)  # noqa: E731
    return [
        _sensor("GPSSensor", "GPSSensor", "Platform", hz(5), {"Sigma": 0.5, "Depth": 1, "DepthSigma": 0.25}),
        _sensor("IMUSensor", "IMUSensor", "Platform", hz(ticks), {
            "AccelSigma": 0.00277, "AngVelSigma": 0.00123, "AccelBiasSigma": 0.00141, "AngVelBiasSigma": 0.00388,
            "ReturnBias": True}),
        # keys as HoloOcean's URaycastSemanticLidar::ParseSensorParms reads them; Range in metres
        _sensor("RaycastSemanticLidar", "SemanticLidar", "Platform", hz(10), {
            "Channels": 16, "Range": 60.0, "PointsPerSecond": 100000, "RotationFrequency": float(hz(10)),
            "UpperFovLimit": 15.0, "LowerFovLimit": -15.0, "HorizontalFov": 360.0}),
        _sensor("RGBCamera", "FrontCamera", "Platform", hz(10), {"CaptureWidth": 512, "CaptureHeight": 512}),
    ]


def _clear_of_objects(scene, gx, gy, margin_m: float) -> np.ndarray:
    ok = np.ones(gx.shape, bool)
    for o in scene.objects:
        r = 0.5 * float(np.hypot(o.length_m * max(o.scale[0], 1e-6), o.width_m * max(o.scale[1], 1e-6))) + margin_m
        ok &= np.hypot(gx - o.x_m, gy - o.y_m) > r
    veg = scene.vegetation
    if veg is not None and len(veg):  # up to tens of thousands of instances: a k-d tree, not a loop
        from scipy.spatial import cKDTree

        d, _ = cKDTree(np.stack([veg.x_m, veg.y_m], 1)).query(np.stack([gx.ravel(), gy.ravel()], 1),
                                                               distance_upper_bound=margin_m)
        ok &= (d > margin_m).reshape(gx.shape)
    return ok


def _pick(score: np.ndarray, ok: np.ndarray) -> tuple[int, int] | None:
    if not ok.any():
        return None
    s = np.where(ok, score, -np.inf)
    r, c = np.unravel_index(int(np.argmax(s)), s.shape)
    return int(r), int(c)


def place_agents(scene, grid_px: int = 128):
    """(auv_xyz, vessel_xyz): the AUV where the water is deep and open, the vessel on open water away from it."""
    from scipy.ndimage import distance_transform_edt

    ew, eh = scene.extent_m
    nx = max(8, min(grid_px, scene.height.shape[1]))
    ny = max(8, min(grid_px, scene.height.shape[0]))
    gx, gy = vertex_grid(scene.extent_m, nx, ny)
    z = resample_height(scene, nx, ny)
    water = (sample_class(scene, gx, gy) == WATER) & (z < 0)
    cell = max(ew / (nx - 1), eh / (ny - 1))
    # distance (m) to the nearest non-water cell or the level's border: prefer open water
    pad = np.pad(water, 1, constant_values=False)
    open_m = distance_transform_edt(pad)[1:-1, 1:-1] * cell
    margin = 2.0
    auv_ok = water & (-z >= AUV_MIN_WATER_M) & _clear_of_objects(scene, gx, gy, margin)
    ij = _pick(-z + 0.25 * open_m, auv_ok)
    if ij is None:
        raise InputError(
            f"scene {scene.name!r} has no water at least {AUV_MIN_WATER_M} m deep clear of objects, so the "
            "HoloOcean AUV cannot be placed; export without 'holoocean' or raise terrain.max_depth_m")
    depth = float(-z[ij])
    auv_z = -min(max(AUV_DEPTH_MARGIN_M, depth / 2.0), depth - AUV_DEPTH_MARGIN_M)
    auv = (float(gx[ij]), float(gy[ij]), auv_z)
    away = np.hypot(gx - auv[0], gy - auv[1])
    v_ok = water & (-z >= VESSEL_MIN_WATER_M) & _clear_of_objects(scene, gx, gy, margin + 2.0) & (away >= 5.0)
    vij = _pick(open_m + 0.1 * np.minimum(away, 30.0), v_ok)
    if vij is None:  # a small pond: share the AUV's open water, still clear of objects
        vij = _pick(open_m, water & _clear_of_objects(scene, gx, gy, margin + 2.0))
    if vij is None:
        raise InputError(f"scene {scene.name!r} has no open water clear of objects for the HoloOcean SurfaceVessel")
    vessel = (float(gx[vij]), float(gy[vij]), 0.0)
    return auv, vessel, float(z.min()), float(z.max())


def build_scenario(scene, config) -> tuple[dict, dict]:
    ticks = int(config.ticks_per_sec)
    if ticks <= 0:
        raise InputError(f"export.ticks_per_sec = {ticks} must be a positive integer")
    world = safe_name(scene.name)
    auv, vessel, zmin, zmax = place_agents(scene)
    ew, eh = scene.extent_m
    margin = 10.0
    env_min = [-ew / 2.0 - margin, -eh / 2.0 - margin, zmin - margin]
    tallest = max([o.z_m + 10.0 for o in scene.objects] + [zmax + 10.0])
    env_max = [ew / 2.0 + margin, eh / 2.0 + margin, tallest + margin]
    sonar_range = float(min(40.0, max(10.0, 0.5 * min(ew, eh))))
    scenario = {
        "name": SCENARIO_NAME, "world": world, "package_name": config.package_name, "main_agent": "auv0",
        "ticks_per_sec": ticks, "frames_per_sec": ticks,
        "env_min": [round(v, 3) for v in env_min], "env_max": [round(v, 3) for v in env_max],
        "octree_min": 0.1, "octree_max": 5.0,
        "agents": [
            {"agent_name": "auv0", "agent_type": "HoveringAUV", "sensors": auv_sensors(ticks, sonar_range),
             "control_scheme": 0, "location": [round(v, 3) for v in auv], "rotation": [0.0, 0.0, 0.0]},
            {"agent_name": "vessel0", "agent_type": "SurfaceVessel", "sensors": vessel_sensors(ticks),
             "control_scheme": 0, "location": [round(v, 3) for v in vessel], "rotation": [0.0, 0.0, 0.0]},
        ],
    }
    check_rates(scenario)
    world_entry = {"name": world, "pre_start_steps": 2, "env_min": scenario["env_min"], "env_max": scenario["env_max"]}
    return scenario, world_entry


def readme(scenario: dict, package: str) -> str:
    w = scenario["world"]
    return "\n".join([
        f"# HoloOcean scenario for {w}",
        "",
        f"Written by coastforge {__version__} for HoloOcean 2.x (Unreal Engine 5.3).",
        "",
        f"1. Build and package the level with the `ue5` bundle; name the map `{w}`.",
        f"2. Copy `{w}-{scenario['name']}.json` into the package folder `worlds/{package}/`.",
        f"3. Add the object in `config_world_entry.json` to the `worlds` list of `worlds/{package}/config.json`; "
        "`holoocean.make` fails for a world missing there.",
        f"4. `holoocean.make(\"{w}-{scenario['name']}\")`, or pass the JSON as `scenario_cfg=`.",
        "",
        "Agents: `auv0` (HoveringAUV, in deep open water, clear of objects) and `vessel0` (SurfaceVessel on open "
        "water). Locations are metres in HoloOcean's frame (x east, y north, z up, water surface at z = 0). "
        f"Every sensor's Hz divides ticks_per_sec ({scenario['ticks_per_sec']}), so HoloOcean runs it at exactly "
        "that rate; env_min/env_max enclose the whole level.",
        "",
        "Semantics: `SemanticCamera` (SemanticSegmentationCamera) and `SemanticLidar` (RaycastSemanticLidar) report "
        "HoloOcean's labels, which the ue5 bundle puts first in every actor's tags; `../instances.json` lists each "
        "object's label and stencil value (`holoocean_id`). Both sensors are in HoloOcean's develop branch (after "
        "2.2.0): remove them from the JSON for an older release. Floating boats and buoys carry the tag `Float`, so "
        "a `tide` in the scenario moves them with the water.",
        "",
    ])


def export_holoocean(scene, assets, config) -> dict[str, bytes]:
    scenario, entry = build_scenario(scene, config)
    dump = lambda d: (json.dumps(d, indent=2, allow_nan=False) + "\n").encode("utf-8")  # noqa: E731
    return {f"{scenario['world']}-{scenario['name']}.json": dump(scenario),
            "config_world_entry.json": dump(entry),
            "README.md": readme(scenario, config.package_name).encode("utf-8")}
