"""Plain helpers that import nothing from rayvr: the files users give (regular files under a size cap,
one-line errors), results written atomically, signal handlers held for a block, and the optional
packages a command needs, named by the extra that installs them.
"""
