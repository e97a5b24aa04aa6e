"""`python -m penumbra …`: see engine/cli.py."""
import sys

from penumbra.engine.cli import main

sys.exit(main())
