"""``generate``: one image in, one complete scene out.

- ``generate``: ``run_generate``, the front door (inputs checked, the image's front end chosen, an
  all-or-nothing output folder); ``request``: what it is asked for and what it returns.
- ``chain``: ``run_chain``, the one stage order, for any ``FrontEnd``: ``whole.WholeImage`` (an image in
  memory) or ``tiled.TiledImage`` (a large one read by windows, with ``tiling``'s tiled stages).
- ``assemble`` (the scene's parts), ``libraries`` (the run's asset libraries), ``outputs`` (the files
  written beside the scene), ``side`` (the side process's jobs): the chain's pieces.
- ``runtime``: what runs beside the chain (stage timer, background jobs, side process).
"""

from .assemble import fill_under_objects
from .chain import FrontEnd, report_waiter, run_chain
from .generate import run_generate
from .request import GenerateRequest, GenerateResult, Progress
from .tiled import TiledImage, generate_tiled
from .whole import WholeImage

__all__ = ["FrontEnd", "GenerateRequest", "GenerateResult", "Progress", "TiledImage", "WholeImage",
           "fill_under_objects", "generate_tiled", "report_waiter", "run_chain", "run_generate"]
