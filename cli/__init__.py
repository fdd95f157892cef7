"""collide command line (installed as the collide_cli package)."""
