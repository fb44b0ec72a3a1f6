"""The application: the ``cmanip`` command line and run configuration. Imports every layer;
nothing imports it."""
