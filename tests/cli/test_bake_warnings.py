"""atlasgen bake's warnings (issue 21): one line per material that the atlas cannot hold faithfully,
printed unless -q, and a failure with nothing written under --strict."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

from atlasgen.cli.main import app
from atlasgen.errors import BakeWarnings

ANISOTROPIC = (
    'type = "bsdf"\nbsdf = { type = "roughconductor", alpha_u = 0.1, alpha_v = 0.4 }\naccept_anisotropy = true\ngloss = 0.5\n'
)
PLASTIC = 'type = "bsdf"\nbsdf = { type = "plastic", diffuse_reflectance = 0.2 }\nrough_only = true\ngloss = 0.5\n'


@pytest.mark.slow
@pytest.mark.parametrize("body, cause", [(ANISOTROPIC, "the BSDF is anisotropic"), (PLASTIC, "dropped a smooth (delta) lobe")])
def test_a_consented_loss_warns_and_strict_fails_writing_nothing(mitsuba_llvm, write_material, tmp_path, body, cause):
    write_material("odd", body)
    out = tmp_path / "out" / "a.dds"
    args = ["bake", str(tmp_path / "materials"), "-o", str(out)]
    strict = CliRunner().invoke(app, args + ["--strict"])
    assert strict.exit_code == BakeWarnings.exit_code == 7, strict.output
    (line,) = strict.stderr.splitlines()
    assert line.startswith("atlasgen: error: --strict: 1 material warning, no atlas written: ") and cause in line, line
    assert "odd.toml: material 'odd'" in line and not (tmp_path / "out").exists()

    plain = CliRunner().invoke(app, args)
    assert plain.exit_code == 0 and out.exists()
    warnings = [x for x in plain.stderr.splitlines() if x.startswith("atlasgen: warning: ")]
    assert len(warnings) == 1 and cause in warnings[0], plain.stderr
    quiet = CliRunner().invoke(app, args + ["-q"])
    assert quiet.exit_code == 0 and quiet.stderr == ""


@pytest.mark.parametrize("body", ['type = "lambert"\nrgb_scale = 0.01\n', 'type = "fresnel"\nalpha_scale = 1e-3\n'])
def test_texels_clamped_to_a_scale_given_fail_strict_as_every_material_warning(write_material, tmp_path, body):
    """The finding: a scale below the slice's peak clamped a third of its texels with a warning, and --strict wrote
    the atlas all the same (exit 0), where the opposite mistake (a scale that stores 0) exited 7."""
    write_material("dim", body)
    out = tmp_path / "out" / "a.dds"
    args = ["bake", str(tmp_path / "materials"), "-o", str(out)]
    strict = CliRunner().invoke(app, args + ["--strict"])
    assert strict.exit_code == BakeWarnings.exit_code, strict.output
    (line,) = strict.stderr.splitlines()
    assert (
        line.startswith("atlasgen: error: --strict: 1 material warning, no atlas written: ")
        and "dim.toml: material 'dim'" in line
    )
    assert "of texel channels to the slice scale" in line and not (tmp_path / "out").exists()
    plain = CliRunner().invoke(app, args)
    assert plain.exit_code == 0 and out.exists()
    (warning,) = [x for x in plain.stderr.splitlines() if x.startswith("atlasgen: warning: ")]
    assert "clamped" in warning and "dim.toml: material 'dim'" in warning


@pytest.mark.parametrize("after_s, quiet, shown", [(0.0, False, True), (0.0, True, False), (3600.0, False, False)])
def test_a_long_bake_reports_each_material_on_stderr(write_material, tmp_path, monkeypatch, after_s, quiet, shown):
    """Past PROGRESS_AFTER_S each baked material is one stderr line (not a terminal here); -q silences it,
    and a bake quicker than that prints none."""
    monkeypatch.setattr("atlasgen.cli.main.PROGRESS_AFTER_S", after_s)
    write_material("clay", 'type = "lambert"\n')
    write_material("sand", 'type = "lambert"\ncolour = [0.8, 0.7, 0.5]\n')
    args = ["bake", str(tmp_path / "materials"), "-o", str(tmp_path / "a.dds")] + (["-q"] if quiet else [])
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    expected = ["baked clay (1/2)", "baked sand (2/2)"] if shown else []
    assert [x for x in result.stderr.splitlines() if x.startswith("baked ")] == expected
