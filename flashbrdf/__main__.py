"""`python -m flashbrdf` is the `flashbrdf` command."""
import sys

from flashbrdf.pipeline.cli import main

sys.exit(main())
