"""Studies: what measures the product rather than tests it; not in the wheel.

``python -m studies`` lists them (``studies/__main__.py``).
"""
