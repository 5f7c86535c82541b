import sys

from taimill.cli import main

sys.exit(main())
