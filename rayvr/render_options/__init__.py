"""The render options, declared where nothing heavy is imported: one module per area, holding its
options' declarations (rayvr/options.py) and the constants they name (allowed values, bounds).
The passes and modules that use an option import it from here, never the reverse, so
`import rayvr.settings` (which collects them all) loads no GL, no pass and no BVH code
(tests/test_import_cycles.py checks it). Importing the package imports nothing."""
