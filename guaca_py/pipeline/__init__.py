"""Pipeline configuration, frame state and the renderer that runs passes in order."""
