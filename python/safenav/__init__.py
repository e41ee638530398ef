"""safenav: GPS-denied safe navigation (placeholder, filled below)."""
