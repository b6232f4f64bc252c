"""navsim's sensor catalog (one datasheet per ``.yaml``), installed as the package
``navsim.data.sensors`` (see pyproject.toml); no code lives here."""
