"""navsim's shipped aircraft (one JSBSim folder each), installed as the package
``navsim.data.aircraft`` (see pyproject.toml); no code lives here."""
