"""Every physical reference describes the same material as its model: each model parameter
reaches the reference, or the model lists it as a deliberate omission with its reason."""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path

import numpy as np
import pytest

from atlasgen.models import get_model, model_types
from atlasgen.models.backlit import translucency, transmitted_albedo
from atlasgen.optics.quadrature import gauss_legendre_rule
from atlasgen.optics.thin_film import film_average, film_table, thin_film_f_cos

DOCS = Path(__file__).resolve().parents[2] / "docs" / "validation.md"
#: Bases for the perturbations where the defaults switch a feature off (a back-light of 0).
_BASES = {
    "iridescent": {"backlight": 1.0, "colour": (0.2, 0.1, 0.3)},
    "bsdf": {"bsdf": {"type": "roughplastic", "alpha": 0.2}, "gloss": 0.5},
}


def _values(type_name: str) -> dict:
    return {**{p.name: p.default for p in get_model(type_name).params}, **_BASES.get(type_name, {})}


def _perturbed(param, value):
    """Another valid value of ``param``: inside its bounds and different from ``value``."""
    if param.kind == "bool":
        return not value
    if param.kind == "choice":
        return next(c for c in param.choices if c != value)
    if param.kind == "colour":
        return tuple(0.5 * c + 0.25 for c in value) if tuple(value) != (0.5, 0.5, 0.5) else (0.3, 0.2, 0.1)
    if param.kind == "table":  # a Mitsuba BSDF dict: another roughness
        return {**value, "alpha": 0.5 * (value.get("alpha", 0.1) + 1.0)}
    if param.kind in ("float_list", "colour_list"):
        return type(value)(np.asarray(value, dtype=np.float64)[::-1].tolist())
    hi = param.hi if param.hi is not None else 2.0 * abs(value) + 1.0
    lo = param.lo if param.lo is not None else -hi
    return 0.5 * (value + hi) if value != hi else 0.5 * (value + lo)


def _fingerprint(reference) -> str:
    return json.dumps(dataclasses.asdict(reference), sort_keys=True, default=str)


@pytest.mark.parametrize("type_name", model_types())
@pytest.mark.slow
def test_every_parameter_reaches_the_physical_reference_or_is_a_documented_omission(type_name):
    model = get_model(type_name)
    values = _values(type_name)
    reference = model.physical_reference(values)
    if reference is None:
        assert model.no_physical_reference, f"{type_name}: no physical reference and no reason given"
        assert not model.physical_omissions
        return
    assert not model.no_physical_reference, f"{type_name} has a physical reference but says it has none"
    names = {p.name for p in model.params}
    assert set(model.physical_omissions) <= names, f"omissions name no parameter: {set(model.physical_omissions) - names}"
    assert all(len(reason) > 20 for reason in model.physical_omissions.values())
    base = _fingerprint(reference)
    for param in model.params:
        if param.name in model.physical_omissions:
            continue
        changed = {**values, param.name: _perturbed(param, values[param.name])}
        model.check(changed, "test.toml")
        assert _fingerprint(model.physical_reference(changed)) != base, (
            f"{type_name}.{param.name} does not reach the physical reference; use it, or list it in physical_omissions"
        )


def test_docs_name_every_omission_and_no_parameter_that_does_not_exist():
    text = DOCS.read_text(encoding="utf-8")
    section = text[text.index("### Physical references") :]
    section = section[: section.index("\n## ")]
    for type_name in model_types():
        model = get_model(type_name)
        for name in model.physical_omissions:
            assert f"`{name}`" in section, f"docs/validation.md does not name {type_name}'s omitted `{name}`"
    every = {p.name for t in model_types() for p in get_model(t).params}
    for named in re.findall(r"omits ([^.]*)\.", section):
        for name in re.findall(r"`([a-z_]+)`", named):
            assert name in every, f"docs/validation.md names a parameter no model has: {name}"


def _directions(rng, n, below=False):
    d = rng.normal(size=(n, 3))
    d[:, 2] = np.abs(d[:, 2]) + 0.05
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    if below:
        d[:, 2] *= -1.0
    return d


_FILM = {"thickness": 420.0, "film_ior": 1.45, "base_ior": 1.8, "base_k": 0.0}


def _film_f_cos(wo_below=False, base=0.0, back=None, **film):
    rng = np.random.default_rng(5)
    wi, wo = _directions(rng, 200), _directions(rng, 200, wo_below)
    lam = rng.uniform(380.0, 780.0, size=(200, 4))
    spectrum = np.full((200, 4), base)
    back_spectrum = None if back is None else np.full((200, 4), back)
    return wi, wo, lam, thin_film_f_cos(wi, wo, lam, {**_FILM, **film}, 0.3, spectrum, back_spectrum)


def test_film_strength_scales_the_film_and_split_moves_it_into_a_rough_part():
    *_, plain = _film_f_cos()
    *_, strong = _film_f_cos(film_strength=3.0)
    np.testing.assert_allclose(strong, 3.0 * plain, rtol=1e-12)
    wi, wo, lam, rough = _film_f_cos(film_split=1.0)
    table = film_table(*_FILM.values())
    from atlasgen.optics.thin_film import _lookup

    expected = _lookup(table, wi[:, 2:3], lam) / np.pi * wo[:, 2:3]
    np.testing.assert_allclose(rough, expected, rtol=1e-12)
    *_, half = _film_f_cos(film_split=0.25)
    np.testing.assert_allclose(half, 0.75 * plain + 0.25 * rough, rtol=1e-12)


def test_coupled_energy_divides_the_base_by_one_minus_the_films_average():
    wi, wo, lam, none = _film_f_cos(base=1.0, film_strength=0.0)
    *_, coupled = _film_f_cos(base=1.0, film_strength=0.0, energy="coupled")
    grid, average = film_average(*_FILM.values())
    np.testing.assert_allclose(coupled, none / (1.0 - np.interp(lam, grid, average)), rtol=1e-12)
    # R_avg = 2 int R c dc against Gauss-Legendre on the exact film reflectance.
    x, w = gauss_legendre_rule(64)
    c = 0.5 * (x + 1.0)
    from atlasgen.models.iridescent import film_reflectance

    exact = (w * c) @ film_reflectance(c, grid[::50], *_FILM.values())
    np.testing.assert_allclose(average[::50], exact, atol=2e-5)


def test_the_backlight_transmits_from_behind_through_the_film():
    wi, wo, lam, dark = _film_f_cos(wo_below=True, back=0.7)
    assert np.all(dark == 0.0)  # backlight 0: no transmission
    *_, lit = _film_f_cos(wo_below=True, back=0.7, backlight=2.0, backlight_distortion=0.3, backlight_power=3.0)
    # Diffuse transmission of the model's term's energy for light along -N: 2 (1 - 0.3)^3 / 5.
    gain = 2.0 * 2.0 * 0.7**3 / 5.0
    from atlasgen.optics.thin_film import _lookup

    expected = gain * 0.7 / np.pi * -wo[:, 2:3] * (1.0 - _lookup(film_table(*_FILM.values()), wi[:, 2:3], lam))
    np.testing.assert_allclose(lit, expected, rtol=1e-12)
    assert np.all(wo[:, 2] < 0.0) and np.all(lit > 0.0)


@pytest.mark.parametrize("distortion, power", [(0.0, 1.0), (0.3, 3.0), (0.8, 12.0)])
def test_the_sheets_transmittance_is_the_energy_the_models_term_passes(distortion, power):
    """2 int_0^1 t(-1, c) c dc of the model's own term (Gauss-Legendre) against the closed form."""
    x, w = gauss_legendre_rule(64)
    c = 0.5 * (x + 1.0)
    numeric = np.sum(w * c * translucency(-np.ones_like(c), c, distortion, power))
    assert transmitted_albedo(distortion, power) == pytest.approx(numeric, rel=1e-10)
