"""osmap: texture, solid-texture and surface-grid synthesis with the Oriented and Scalable Map."""

__version__ = "0.1.0"
