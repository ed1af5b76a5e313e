"""Named parameter sets (TOML files in this folder), shipped as package data."""
