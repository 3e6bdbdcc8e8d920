"""Shared formulas: sRGB, 8-bit encoding, Fresnel, microfacet terms, quadrature, atlas interpolation."""
