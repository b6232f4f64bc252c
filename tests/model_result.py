"""Read a measurement model's result in the tests: ``z, H, R, valid``, whether ``model()``
returns a typed result (attributes ``z``, ``H``, ``R``, ``valid``) or the positional tuple."""


def unpack(result) -> tuple:
    """``(z, H, R, valid)`` of a measurement model's result."""
    if all(hasattr(result, k) for k in ("z", "H", "R", "valid")):
        return result.z, result.H, result.R, result.valid
    z, H, R, valid = result
    return z, H, R, valid
