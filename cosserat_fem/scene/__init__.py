"""The scene: keys declared once (keys), the TOML schema, the resolved scene's dataclasses, building
and checking a scene (build), expressions, loads from data."""
