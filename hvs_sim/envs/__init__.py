"""Gymnasium environments (registered on `import hvs_sim`)."""
