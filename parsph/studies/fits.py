"""Fits the studies share: orders of convergence from errors at several resolutions, and straight lines
through measured costs that span orders of magnitude.

A least-squares line through costs of sizes 100x apart is pulled to the
largest unless the residuals are taken relative to each cost, which is how
the scaling model's per-unit costs are fitted (:func:`relative_line`).
"""
import math

import numpy as np


def loglog_slope(x, y):
    """The least-squares slope of log(y) against log(x) (an observed order p in y ~ x^p; NaN with fewer
    than two points)."""
    if len(x) < 2:
        return math.nan
    return float(np.polyfit(np.log(x), np.log(y), 1)[0])


def local_orders(x, y):
    """The order between each pair of successive points, log(y_i / y_i+1) / log(x_i / x_i+1)."""
    return [math.log(y[i] / y[i + 1]) / math.log(x[i] / x[i + 1]) for i in range(len(x) - 1)]


def relative_line(x, y, intercept=None):
    """(slope, intercept) of y = slope x + intercept by least squares of the relative residuals
    (y - line) / y; with ``intercept`` given, through it (the slope alone fitted)."""
    w = 1.0 / np.asarray(y)
    if intercept is None:
        slope, b = np.polyfit(x, y, 1, w=w)
        return slope, b
    return float(np.dot(w * w * x, y - intercept) / np.dot(w * w * x, x)), intercept
