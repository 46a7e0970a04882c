import sys

from paper_repro.cli.main import main

sys.exit(main())
