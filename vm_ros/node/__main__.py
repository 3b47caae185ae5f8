import sys

from vm_ros.node import main

sys.exit(main())
