"""Desktop stereo preview: `python app.py [SCENE] [--materials FILE]` (same as `rayvr preview`)."""
import sys

from rayvr.cli import main

if __name__ == "__main__":
    sys.exit(main(["preview", *sys.argv[1:]]))
