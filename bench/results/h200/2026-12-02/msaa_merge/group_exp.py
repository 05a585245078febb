# bench vr with another MSAA trace workgroup size (primary_rays.MSAA_GROUP, read when a pass is set up)
import os
import sys

import rayvr.frame.passes.primary_rays as pr

pr.MSAA_GROUP = int(os.environ.get("MSAA_GROUP", "64"))
from rayvr.cli import main  # noqa: E402

sys.exit(main(sys.argv[1:]))
