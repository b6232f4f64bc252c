"""navsim's shipped scenarios (one ``.yaml`` each; sweep files in ``sweeps/``), installed as the
package ``navsim.data.scenarios`` (see pyproject.toml), so that ``navsim new scenario NAME --from
SHIPPED`` finds them in a wheel as in a checkout; no code lives here."""
