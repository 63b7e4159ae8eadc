"""The names of the multipath geometries, in a module light enough for the command line."""

PATHS: tuple[str, ...] = ("triangle", "double")
AUTO = "auto"
PATH_CHOICES: tuple[str, ...] = (AUTO, *PATHS)
