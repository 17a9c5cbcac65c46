import sys

from verticality.cli import main

sys.exit(main())
