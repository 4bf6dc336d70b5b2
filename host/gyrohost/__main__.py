import sys

from gyrohost.cli import main

sys.exit(main())
