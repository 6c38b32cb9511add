"""``python -m coastforge.assets.kit --out DIR``: write the starter kit (see ``build.main``)."""

from .build import main

raise SystemExit(main())
