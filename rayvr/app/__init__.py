"""The front ends under the command line: capture (its files, multi-view sources), the preview and its
HUD, and the cluster that spreads captures and sweeps over Ray workers.
"""
