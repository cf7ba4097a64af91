"""`python -m flashbrdf` is the `flashbrdf` command."""
import sys

from flashbrdf.cli.main import main

sys.exit(main())
