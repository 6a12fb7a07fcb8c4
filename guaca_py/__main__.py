"""`python -m guaca_py` is the `guaca` command."""

from .cli import main

raise SystemExit(main())
