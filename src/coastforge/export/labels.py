"""One label table per scene (``instances.json``, DESIGN.md §3) and the engine conventions it feeds.

``instances_table(scene)`` is a pure function of the scene: every terrain class and object class gets a
numeric id and a HoloOcean label, every object of scene.json an instance id (1..N in scene order, 0 = none)
and its label. Every exporter takes its labels from here, so UE/HoloOcean (first actor tag), glTF (node
``extras``), USD (semantics schemas), SDF (Gazebo Label plugin) and the HoloOcean scenario agree.

Where each convention was looked up:

- HoloOcean labels: ``ATagger::GetLabelByFolderName`` recognises exactly ``HOLOOCEAN_LABELS`` (anything else
  is ``None``), with the stencil values of ``holoocean::ObjectLabel`` (ObjectLabel.h); ``ATagger::TagActor``
  labels an actor by its FIRST actor tag when it has tags, else by the grandparent Content folder of its
  static mesh (``GetLabelByPath``: ``StringArray[Num - 3]`` of the object path split on '/'). Source:
  HoloOcean engine ``Holodeck/Utils`` Tagger.cpp / Tagger.h / ObjectLabel.h, and the label table of
  byu-holoocean/holoocean-docs ``develop/_sources/develop/env-docs/custom-semantics.rst.txt``
  ("Available Semantic Labels": folder title, stencil value).
- Floating props: byu-holoocean/holoocean-docs ``develop/_sources/develop/env-docs/create-env.rst.txt``
  ("Additional Tide Settings for Objects": the keyword ``Float`` in the actor tags).
- USD: ``UsdSemantics.LabelsAPI`` (https://openusd.org/release/api/class_usd_semantics_labels_a_p_i.html,
  ``SemanticsLabelsAPI:<taxonomy>`` with ``token[] semantics:labels:<taxonomy>``) and Isaac Sim's legacy
  ``SemanticsAPI:Semantics`` (``semantic:Semantics:params:semanticType/semanticData``), which NVIDIA's
  SimReady rule SL.002 accepts beside an equal LabelsAPI label
  (https://nvidia.github.io/simready-foundation/latest/capabilities/semantic_labels/requirements/semantic-label-deprecated-schema.html).
- Gazebo: the Label system ``<plugin filename="gz-sim-label-system" name="gz::sim::systems::Label">``
  with an integer ``<label>`` in 0..255 (https://gazebosim.org/api/sensors/6/segmentationcamera_igngazebo.html,
  https://gazebosim.org/api/sim/8/Label_8hh_source.html).
"""

from __future__ import annotations

from typing import Any

from ..classes import TERRAIN_CLASSES, WATER

FORMAT = "coastforge.instances/1"

# holoocean::ObjectLabel (ObjectLabel.h): the names ATagger::GetLabelByFolderName accepts, with their stencil
# values. The enum order is the stencil order (None = 0 is not a label a tag can ask for).
HOLOOCEAN_LABELS: dict[str, int] = {name: i + 1 for i, name in enumerate((
    "Cube", "Sphere", "BaseShape", "Landscape", "GroundGrass", "GroundRock", "Ground", "GroundPath", "WaterPlane",
    "Boat", "Yacht", "ContainerBoat", "Concrete", "Pipe", "PipeCover", "VentCover", "Rock", "Seaweed", "Coral",
    "Plane", "Sub", "Pier", "Buoy", "Trash", "Grass", "Asphalt", "Bench", "BikeRack", "Building", "Bus", "Bush",
    "Car", "Ceiling", "Chair", "Cone", "Crate", "Desk", "Dumpster", "FireHydrant", "Floor", "GarbageCan", "Pallet",
    "ParkingGate", "PatioUmbrella", "Railing", "SemiTruck", "Sidewalk", "SpeedLimitSign", "StopSign",
    "StreetLamps", "Table", "Tree", "Wall", "Unlabeled"))}
FLOAT_TAG = "Float"  # HoloOcean's tide system moves actors carrying this tag with the water level

# terrain class -> HoloOcean label. The ground classes use HoloOcean's ground labels and leave Grass, Tree and
# Rock to the scattered props standing on them: 'trees' is the forest floor under the tree instances (Ground),
# 'rocks' is rocky ground such as a revetment (GroundRock), and HoloOcean has no sand label (Ground).
TERRAIN_LABELS: dict[str, str] = {c.name: c.holoocean_name for c in TERRAIN_CLASSES}

# object classes (after the 8 terrain classes): detected objects and scattered vegetation/rock instances
OBJECT_CLASSES: tuple[str, ...] = ("boat", "vehicle", "pier", "buoy", "tree", "bush", "grass", "rock", "seaweed")
OBJECT_LABELS: dict[str, str] = {"boat": "Boat", "vehicle": "Car", "pier": "Pier", "buoy": "Buoy", "tree": "Tree",
                                 "bush": "Bush", "grass": "Grass", "rock": "Rock", "seaweed": "Seaweed"}
FLOATING_CLASSES = ("boat", "buoy")
# what an asset id says about a 'vegetation' instance (the starter kit's ids: bush_round, grass_dry, ...)
VEGETATION_WORDS = (("bush", "bush"), ("grass", "grass"), ("seaweed", "seaweed"), ("kelp", "seaweed"),
                    ("rock", "rock"))


def class_id(name: str, kind: str = "object") -> int:
    """Numeric class id: terrain classes keep their ids 0..7, object classes follow from 8."""
    if kind == "terrain":
        return next(c.id for c in TERRAIN_CLASSES if c.name == name)
    return len(TERRAIN_CLASSES) + OBJECT_CLASSES.index(name)


def object_class(category: str, asset_id: str = "") -> str:
    """The semantic class of a scene object or vegetation instance: its category, except that the category
    ``vegetation`` (scene objects and the vegetation table alike) is told apart by the asset id (the starter
    kit's ``tree_*``, ``bush_*``, ``grass_*``, ``seaweed_*``, ``rock_*``; anything else is a tree)."""
    if category in OBJECT_CLASSES:
        return category
    a = asset_id.lower()
    return next((cls for word, cls in VEGETATION_WORDS if word in a), "tree")


def object_label(cls: str, asset_id: str = "") -> str:
    """HoloOcean label of an object class; vehicles by what the asset says (a bus, a truck), else Car."""
    if cls == "vehicle":
        a = asset_id.lower()
        if "bus" in a:
            return "Bus"
        if "truck" in a and "pickup" not in a:  # HoloOcean's only truck label; a pickup is a car
            return "SemiTruck"
    return OBJECT_LABELS.get(cls, "Unlabeled")


def is_floating(scene, o) -> bool:
    """A boat or buoy on water (not ashore): HoloOcean's tide moves it and UE files it under float/."""
    if object_class(o.category, o.asset_id) not in FLOATING_CLASSES or o.attrs.get("ashore"):
        return False
    if scene.classes is None or scene.height is None:
        return abs(o.z_m - scene.water_level_m) < 0.5
    from .terrain_mesh import sample_class

    return int(sample_class(scene, o.x_m, o.y_m)) == WATER


def instances_table(scene) -> dict[str, Any]:
    """The scene's label table (``instances.json``): classes with ids and HoloOcean labels, every object with
    its instance id (1..N in scene order; 0 means none), class, label and whether it floats."""
    # terrain classes: also the UE landscape paint layer holding each (ue5.LAYER_NAMES), since HoloOcean's
    # Tagger labels static meshes only and the landscape carries the classes as layers
    classes = [{"name": c.name, "kind": "terrain", "id": c.id, "holoocean": TERRAIN_LABELS[c.name],
                "holoocean_id": HOLOOCEAN_LABELS[TERRAIN_LABELS[c.name]], "ue_layer": c.name.capitalize(),
                "usd_subset": c.name} for c in TERRAIN_CLASSES]
    classes += [{"name": n, "kind": "object", "id": class_id(n), "holoocean": OBJECT_LABELS[n],
                 "holoocean_id": HOLOOCEAN_LABELS[OBJECT_LABELS[n]]} for n in OBJECT_CLASSES]
    objects = []
    for k, o in enumerate(scene.objects, start=1):
        cls = object_class(o.category, o.asset_id)
        label = object_label(cls, o.asset_id)
        objects.append({"id": o.id, "instance_id": k, "category": o.category, "asset_id": o.asset_id,
                        "class": cls, "class_id": class_id(cls) if cls in OBJECT_CLASSES else 0,
                        "holoocean": label, "holoocean_id": HOLOOCEAN_LABELS[label],
                        "floating": is_floating(scene, o)})
    veg = scene.vegetation
    counts: dict[str, int] = {}
    for c, a in (zip(veg.category, veg.asset_id) if veg is not None else ()):
        name = object_class(str(c), str(a))
        counts[name] = counts.get(name, 0) + 1
    vegetation = [{"class": k, "class_id": class_id(k), "holoocean": OBJECT_LABELS[k],
                   "holoocean_id": HOLOOCEAN_LABELS[OBJECT_LABELS[k]], "count": n} for k, n in sorted(counts.items())]
    return {"format": FORMAT, "scene": scene.name, "instance_id_none": 0, "classes": classes, "objects": objects,
            "vegetation": vegetation,
            "notes": {"instance_id": "1..N in scene.json order; vegetation instances carry their class only (0)",
                      "holoocean": "HoloOcean Tagger label names (ATagger::GetLabelByFolderName); holoocean_id is "
                                   "the custom-depth stencil value of holoocean::ObjectLabel",
                      "sdf_label": "Gazebo Label plugin value = holoocean_id, so both segmentations agree"}}


def labels_by_id(table: dict) -> dict[str, dict]:
    """Object rows of an instances table by object id."""
    return {r["id"]: r for r in table["objects"]}


def vegetation_label(category: str, asset_id: str = "") -> tuple[str, int]:
    """(HoloOcean label, stencil value) of a vegetation instance (its table category and asset id)."""
    label = object_label(object_class(category, asset_id))
    return label, HOLOOCEAN_LABELS[label]


def instances_json(scene) -> bytes:
    import json

    return (json.dumps(instances_table(scene), indent=2, ensure_ascii=False, allow_nan=False) + "\n").encode("utf-8")


__all__ = [
    "FLOAT_TAG",
    "HOLOOCEAN_LABELS",
    "instances_json",
    "instances_table",
    "is_floating",
    "labels_by_id",
    "object_class",
    "object_label",
    "vegetation_label",
]
