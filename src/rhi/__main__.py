"""`python -m rhi`: the `rhi` command."""

import sys

from rhi.cli import main

sys.exit(main())
