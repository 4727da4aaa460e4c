"""The built-in servo laws on the features of control/features.py: IBVS (ibvs.py, with the gain schedule and image
terms the point laws share), PBVS (pbvs.py) and photometric servoing (dvs.py)."""
