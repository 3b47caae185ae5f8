"""``python -m vm_ros.cli``: the same as the ``vm-ros`` command."""

import sys

from vm_ros.cli import main

sys.exit(main())
