"""cli/options.py: an option a mode ignores is refused on one line (exit 2), never accepted silently."""

import click
import pytest
from click.testing import CliRunner

from atlasgen.cli.main import app
from atlasgen.cli.options import refuse_options

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
]  # fmt: skip


@pytest.mark.parametrize(("mode", "option", "words"), IGNORED, ids=[" ".join(m[:2] + o[:1]) for m, o, _ in IGNORED])
def test_an_option_the_mode_ignores_is_refused_on_one_line(tmp_path, write_material, mode, option, words):
    material = write_material("alpha", 'type = "lambert"\n')
    folder = tmp_path / "folder"
    out = tmp_path / "out"
    fill = {"folder": str(folder), "material": str(material)}
    args = [a.format(**fill) for a in [*mode, *option]]
    res = CliRunner().invoke(app, [*args, "-o", str(out / "x.png" if mode[0] == "preview" else out)])
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
