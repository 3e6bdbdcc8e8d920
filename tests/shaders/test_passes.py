"""The renderer's pass sources: the shipped WGSL files with the caller's declarations filled in."""

from __future__ import annotations

from atlasgen.render.layout import FRAME, LIGHT, OBJECT, declaration_wgsl
from atlasgen.shaders.passes import assemble_shader, fill_declarations, read_shader


def test_shader_files_name_shared_structs_and_never_spell_them():
    for name, struct in (("common.wgsl", FRAME), ("gbuffer.wgsl", OBJECT), ("lighting.wgsl", LIGHT)):
        raw = read_shader(name)
        assert f"struct {struct.name} " not in raw and f"// @declare {struct.name}\n" in raw
        assert fill_declarations(raw, declaration_wgsl).count(struct.wgsl()) == 1
    lighting = assemble_shader("common.wgsl", "lighting.wgsl", declare=declaration_wgsl)
    assert "\n// @declare" not in lighting and "const LIGHT_POINT: u32 = 1u;" in lighting
    assert "const NO_MATERIAL: u32 = 65535u;" in lighting


def test_declarations_are_the_callers():
    # The pass assembly knows no declaration itself: each `// @declare NAME` line (trailing blanks
    # allowed, nothing else on it) becomes what the caller's `declare` gives for NAME.
    text = "a\n// @declare Foo\nb\n// @declare Bar \t\n// @declare Baz qux\n"
    filled = fill_declarations(text, lambda name: f"const {name.upper()}: u32 = 1u;\n")
    assert filled == "a\nconst FOO: u32 = 1u;\nb\nconst BAR: u32 = 1u;\n// @declare Baz qux\n"
    include = "const FROM_THE_BAKE: u32 = 7u;\n"
    assembled = assemble_shader("stencil_mask.wgsl", declare=lambda name: "", include=include)
    assert assembled.startswith(f"// ---- generated atlas include ----\n{include}\n// ---- stencil_mask.wgsl ----\n")
    assert assembled.endswith(read_shader("stencil_mask.wgsl"))
