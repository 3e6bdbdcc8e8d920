"""Shared formulas, one implementation each: sRGB, 8-bit encoding, Fresnel, microfacet terms,
quadrature, atlas interpolation, display transforms, the renderer's specular lobe."""
