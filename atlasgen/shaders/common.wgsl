// atlasgen renderer: declarations shared by every pass.
//
// Radiometric units follow Mitsuba 3 exactly (docs/scenes.md): radiance in W/(m^2 sr),
// point lights are radiant intensities I (irradiance I / d^2, windowed to 0 at a range), directional lights are
// irradiances E normal to their direction.
//
// Structs and constants shared with the CPU are declared once, in atlasgen/render/layout.py:
// each "// @declare NAME" line is replaced by its generated WGSL when a pass is assembled.

// @declare Frame

// @declare NO_MATERIAL

// One triangle covering the viewport: no vertex buffer needed.
@vertex
fn vs_fullscreen(@builtin(vertex_index) index: u32) -> @builtin(position) vec4<f32> {
    let xy = vec2<f32>(f32((index << 1u) & 2u), f32(index & 2u));
    return vec4<f32>(xy * 2.0 - 1.0, 0.0, 1.0);
}

// The same triangle on the far plane (depth 1, the depth buffer's clear value): under depth_compare
// "greater" only the pixels some object covers pass, and a rasteriser skips the rest before shading.
@vertex
fn vs_fullscreen_far(@builtin(vertex_index) index: u32) -> @builtin(position) vec4<f32> {
    let xy = vec2<f32>(f32((index << 1u) & 2u), f32(index & 2u));
    return vec4<f32>(xy * 2.0 - 1.0, 1.0, 1.0);
}
