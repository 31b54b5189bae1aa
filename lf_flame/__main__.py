"""``python -m lf_flame ...``: the ``lf-flame`` command line (:mod:`lf_flame.cli`)."""
from .cli import main

raise SystemExit(main())
