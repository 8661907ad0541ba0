import sys

from hybrid_sysid.report.cli import main

sys.exit(main())
