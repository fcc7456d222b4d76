"""Speed and accuracy studies that print tables (``python -m benchmarks.broad``, ``python -m benchmarks.speed``).

Real data comes from ``../shared/data`` (or the folder named by an environment variable) when present;
the benchmarks say so clearly and do nothing when it is absent.  Nothing here is imported by the product.
"""
