"""A variant's cost and error: image metrics, the reference settings, one variant measured, and the
choice of effects under a frame budget (--budget-ms).
"""
