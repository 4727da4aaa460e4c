"""hvs_sim methods from outside the package (tests/plugins): written only against hvs_sim's documented contracts."""
