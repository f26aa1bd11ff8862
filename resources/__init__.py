"""Protocol files, style sheets and icons, found with importlib.resources."""
