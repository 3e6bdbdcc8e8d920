"""Human-facing reports: the library page, the validation pages and the separable study."""
