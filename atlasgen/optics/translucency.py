"""The energy of the Barré-Brisebois & Bouchard back-light term, for its physical counterparts.

The ``backlit`` model's term t = saturate(V.-(L + N delta))^p is a real-time stand-in for
light scattered through a thin object. Its physical references (the ``backlit`` thin sheet,
the ``iridescent`` film's back-light) transmit diffusely the energy t passes for light from
behind along -N, which :func:`transmitted_albedo` gives in closed form.
"""

from __future__ import annotations

__all__ = ["transmitted_albedo"]


def transmitted_albedo(distortion: float, power: float) -> float:
    """2 int_0^1 t(-1, c) c dc: the share of light arriving along -N that the term sends out through the front.

    At N.L = -1 the term has no azimuth (b = 0) and t = saturate(c (1 - delta))^p with
    c = N.V, so the cosine-weighted integral over the viewing hemisphere is
    2 (1 - delta)^p / (p + 2) (delta <= 1): the directional transmittance a diffuse sheet
    must have to pass the same energy.
    """
    return 2.0 * (1.0 - float(distortion)) ** float(power) / (float(power) + 2.0)
