"""Hardware characterisation (paper section III and V-C): one module per fit.

Each fit reads recordings through `load` and returns plain dicts (numbers, small arrays) that
the workflow writes as one JSON artifact per fit; `claims` turns them into claims.csv rows.
"""
