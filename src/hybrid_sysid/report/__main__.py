import sys

from hybrid_sysid.cli.report import main

sys.exit(main())
