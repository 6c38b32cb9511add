"""Scripts that run inside the Unreal Editor (not imported by coastforge itself).

``capture_thumbnails.py`` captures top-down thumbnails of static meshes for
``coastforge library build --from-thumbnails DIR``. Find it with
``python -c "import coastforge.assets.unreal as u, pathlib; print(pathlib.Path(u.__file__).with_name('capture_thumbnails.py'))"``.
"""

from pathlib import Path

CAPTURE_SCRIPT = Path(__file__).with_name("capture_thumbnails.py")
