"""``python -m rgbd_rs.cli``: the ``rgbd`` script."""

import sys

from rgbd_rs.cli import main

sys.exit(main())
