import sys

from facepuppet.cli import main

sys.exit(main())
