"""cli/options.py: an option a mode ignores is refused on one line (exit 2), never accepted silently."""

import contextlib
import io
import sys

import click
import pytest
from click.testing import CliRunner

from atlasgen.cli.main import app
from atlasgen.cli.options import NORMAL, MaterialProgress, refuse_options

# (the command line's mode, the option it ignores, the words of the refusal)
IGNORED = [
    (["validate", "--merge", "{folder}"], ["--spp", "4"], "--spp has no effect with --merge"),
    (["validate", "--merge", "{folder}"], ["--physical-spp", "8"], "--physical-spp has no effect with --merge"),
    (["validate", "--merge", "{folder}"], ["--scene", "front"], "--scene has no effect with --merge"),
    (["validate", "--merge", "{folder}"], ["--atlas", "x.dds"], "--atlas has no effect with --merge"),
    (["validate", "--merge", "{folder}"], ["--environment"], "--environment has no effect with --merge"),
    (["validate", "--merge", "{folder}"], ["--no-reference-cache"], "--no-reference-cache has no effect with --merge"),
    (["validate", "alpha", "--no-reference-cache"], ["--reference-cache", "{folder}"],
     "--reference-cache has no effect with --no-reference-cache"),
    (["report", "separable", "--merge", "{folder}"], ["--repeats", "2"], "--repeats has no effect with --merge"),
    (["report", "separable", "--merge", "{folder}"], ["--library"], "--library has no effect with --merge"),
    (["report", "separable", "--merge", "{folder}"], ["--atlas", "x.dds"], "--atlas has no effect with --merge"),
    (["report", "separable", "--library"], ["-m", "{folder}"], "--materials has no effect with --library"),
    (["preview", "{material}"], ["--reference-spp", "8"], "--reference-spp has no effect without --reference"),
    (["preview", "{material}", "--no-cache"], ["--cache", "{folder}"], "--cache has no effect with --no-cache"),
    (["render", "{material}", "--aov", "depth"], ["--mip-bias", "2"], "--mip-bias has no effect with --aov"),
    (["render", "{material}", "--aov", "normal"], ["--no-outlines"], "--no-outlines has no effect with --aov"),
    (["validate", "alpha", "--no-physical"], ["--physical-spp", "8"], "--physical-spp has no effect with --no-physical"),
    (["report", "separable", "{material}"], ["--library"], "--library has no effect when every NAME is a material file"),
    (["report", "separable", "{material}"], ["-m", "{folder}"], "--materials has no effect when every NAME is a material"),
    (["validate", "alpha", "--no-physical"], ["--max-physical-spp", "8"], "--max-physical-spp has no effect with "
     "--no-physical and no environment scene, where it caps no reference; expected --environment (whose references it "
     "caps), or no --max-physical-spp"),
    (["bake", "{material}"], ["--flatten", "default"], "--flatten has no effect without a MaterialX material among the "
     "inputs; expected a MaterialX document (.mtlx) to flatten, or no --flatten"),
]  # fmt: skip


@pytest.mark.parametrize(("mode", "option", "words"), IGNORED, ids=[" ".join(m[:2] + o[:1]) for m, o, _ in IGNORED])
def test_an_option_the_mode_ignores_is_refused_on_one_line(tmp_path, write_material, mode, option, words):
    material = write_material("alpha", 'type = "lambert"\n')
    folder = tmp_path / "folder"
    out = tmp_path / "out"
    fill = {"folder": str(folder), "material": str(material)}
    args = [a.format(**fill) for a in [*mode, *option]]
    output = {"preview": out / "x.png", "render": out / "x.exr", "bake": out / "x.dds"}.get(mode[0], out)
    res = CliRunner().invoke(app, [*args, "-o", str(output)])
    assert res.exit_code == 2, res.output
    assert res.stderr.strip().splitlines() == [f"atlasgen: error: {res.stderr.split('error: ')[1].strip()}"]
    assert words in res.stderr and "expected " in res.stderr
    assert not out.exists() and not folder.exists()


def test_given_is_what_the_command_line_says_not_a_value_other_than_the_default():
    """An option typed at its default value is refused too (it was asked for); one left out never is."""

    @click.command()
    @click.option("--merge", is_flag=True)
    @click.option("--spp", type=int, default=1)
    def command(merge, spp):
        if merge:
            refuse_options(click.get_current_context(), ("spp",), "with --merge")
        click.echo(f"spp {spp}")

    runner = CliRunner()
    assert runner.invoke(command, ["--merge"]).output == "spp 1\n"
    assert runner.invoke(command, ["--spp", "4"]).output == "spp 4\n"
    refused = runner.invoke(command, ["--merge", "--spp", "1"])
    assert refused.exit_code == 2 and "--spp has no effect with --merge; expected one or the other" in refused.output


@pytest.mark.parametrize(("flag", "name"), [("-q", "--quiet"), ("-v", "--verbose")])
def test_info_s_verbosity_is_refused_with_json_which_it_does_not_change(tmp_path, write_material, flag, name):
    material = write_material("alpha", 'type = "lambert"\n')
    atlas = tmp_path / "a.dds"
    assert CliRunner().invoke(app, ["bake", str(material), "-o", str(atlas), "-q"]).exit_code == 0
    res = CliRunner().invoke(app, ["info", str(atlas), "--format", "json", flag])
    assert res.exit_code == 2 and res.stdout == "", res.output
    assert res.stderr.splitlines() == [f"atlasgen: error: {name} has no effect with --format json, which prints the whole "
                                       "summary; expected one or the other"]  # fmt: skip


@pytest.mark.parametrize("environment", [["--environment"], ["--scene", "env-sky"], ["--scene", "mine.toml"]])
def test_max_physical_spp_is_taken_with_no_physical_where_environment_references_use_it(tmp_path, environment):
    """--environment's references are capped by it too (and an environment scene named, or a scene file that may
    have one): there it has an effect, and is not refused (nor held to --physical-spp's default, which renders
    nothing then)."""
    res = CliRunner().invoke(app, ["validate", "--no-physical", *environment, "--max-physical-spp", "8", "--atlas",
                                   str(tmp_path / "missing.dds"), "-o", str(tmp_path / "out")])  # fmt: skip
    assert res.exit_code == 3 and "missing.dds" in res.stderr, res.output  # it went on, to the atlas


@pytest.mark.parametrize("command", [["validate", "--merge"], ["report", "separable", "--merge"]])
def test_verbose_is_refused_with_a_merge_which_prints_nothing_more(tmp_path, command):
    res = CliRunner().invoke(app, [*command, str(tmp_path / "a"), "-v", "-o", str(tmp_path / "out")])
    assert res.exit_code == 2 and "--verbose has no effect with --merge" in res.stderr, res.output
    assert len(res.stderr.splitlines()) == 1 and not (tmp_path / "out").exists()


def test_a_material_file_with_an_upper_case_extension_is_a_file_not_a_name(tmp_path, write_material):
    """report separable x/UP.TOML looked the name up in materials/ ("materials: no such file or folder")."""
    material = write_material("alpha", 'type = "lambert"\n')
    upper = material.with_name("UP.TOML")
    material.rename(upper)
    res = CliRunner().invoke(app, ["report", "separable", str(upper), "-o", str(tmp_path / "out")])
    assert res.exit_code == 3 and res.stderr.startswith(f"atlasgen: error: {upper.as_posix()}"), res.output


def test_of_a_flag_pair_sharing_one_parameter_only_the_flag_given_is_refused():
    """-q and -v are one parameter, verbosity: refusing --verbose must leave -q, and name the flag given."""
    from atlasgen.cli.options import verbosity_options

    @click.command()
    @verbosity_options()
    def command(verbosity):
        refuse_options(click.get_current_context(), ("--verbose",), "here")
        click.echo(f"verbosity {verbosity}")

    runner = CliRunner()
    assert runner.invoke(command, ["-q"]).output == "verbosity -1\n"
    assert runner.invoke(command, []).output == "verbosity 0\n"
    refused = runner.invoke(command, ["-v"])
    assert refused.exit_code == 2 and "--verbose has no effect here; expected one or the other" in refused.output


class _Terminal(io.StringIO):
    """A stderr that says it is a terminal, so that MaterialProgress draws its bar."""

    def isatty(self):
        return True


@pytest.mark.parametrize("fails", [False, True], ids=["finished", "failed"])
def test_a_progress_bar_is_finished_or_erased_when_the_command_fails(monkeypatch, fails):
    """A bake that failed after its bar was drawn left the bar's line above the error, which was then not the one
    line: the bar is erased instead (a finished bar keeps its line)."""
    terminal = _Terminal()
    monkeypatch.setattr(sys, "stderr", terminal)
    with contextlib.suppress(RuntimeError), MaterialProgress("baked", NORMAL) as report:
        report("clay", 1, 3)
        if fails:
            raise RuntimeError("the bake failed")
    out = terminal.getvalue()
    assert "baked" in out and "clay" in out  # the bar was drawn
    if fails:
        assert out.rsplit("\r", 1)[-1] == "\033[2K\033[?25h" and "\n" not in out
    else:
        assert out.endswith("\n")
