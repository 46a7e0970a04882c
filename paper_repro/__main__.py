import sys

from paper_repro.cli.parser import main

sys.exit(main())
