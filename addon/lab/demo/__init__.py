"""The demo: ``scene`` builds the embedded demo scene, ``job`` runs every tool on it (scripts/demo.py)."""
