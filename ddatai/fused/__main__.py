"""``python -m ddatai.fused``: compile the fused kernel ahead of a session (`ddatai.fused.warm`)."""

import sys

from .warm import main

sys.exit(main())
