"""``python -m sumo_rss`` → the ``sumo-rss`` command line."""
from .cli import main

raise SystemExit(main())
