"""Collection protocols (files) and the Qt-free session runner."""
