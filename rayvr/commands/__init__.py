"""The `rayvr` commands, one module each (`add_parser(sub)` and the command); rayvr/cli.py puts
them together. The render options' flags are generated from their declarations (rayvr/options.py);
`args.py` holds the other shared arguments (the rig, the camera model) and their parsers."""
