"""``python -m flow_node.bag`` = ``flow_bag``."""

import sys

from .cli import main

sys.exit(main())
