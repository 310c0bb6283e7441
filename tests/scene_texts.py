"""Scene files of tests, as TOML text: one copy of each shared by the test files."""

TRANS = """
name = "trans"
description = "tiny transmission scene"
kind = "transmission"
[network]
builder = "triangular"
sizes = [5, 6]
[task]
kind = "source"
"""
