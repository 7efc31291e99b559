"""The paper's study and validation, reproduced.

The 5 × 5 sweeps, the checks against the printed tables, and our model against the
paper's published values.
"""
