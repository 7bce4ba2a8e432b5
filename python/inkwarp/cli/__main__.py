import sys

from inkwarp.cli import main

sys.exit(main())
