"""Built-in device plugins, registered through the tactile_studio.devices entry points."""
