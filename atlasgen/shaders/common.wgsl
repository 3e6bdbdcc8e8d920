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
// @declare FAR_PLANE_DEPTH

// One triangle covering the viewport: no vertex buffer needed.
@vertex
fn vs_fullscreen(@builtin(vertex_index) index: u32) -> @builtin(position) vec4<f32> {
    let xy = vec2<f32>(f32((index << 1u) & 2u), f32(index & 2u));
    return vec4<f32>(xy * 2.0 - 1.0, 0.0, 1.0);
}

// The same triangle on the far plane (FAR_PLANE_DEPTH, the depth buffer's clear value): under depth_compare
// "greater" only the pixels some object covers pass, and a rasteriser skips the rest before shading.
@vertex
fn vs_fullscreen_far(@builtin(vertex_index) index: u32) -> @builtin(position) vec4<f32> {
    let xy = vec2<f32>(f32((index << 1u) & 2u), f32(index & 2u));
    return vec4<f32>(xy * 2.0 - 1.0, FAR_PLANE_DEPTH, 1.0);
}

// The g-buffer's normal_depth target (rg32uint, atlasgen/render/gbuffer.py): x the unit normal in
// octahedral form (Cigolle et al. 2014, "A Survey of Efficient Representations for Independent Unit
// Vectors") as two snorm16, y the view depth's float bits. 8 bytes a pixel instead of 16: a software
// GPU's g-buffer pass and its readers are bound by the bytes they move.
fn sign_not_zero(v: vec2<f32>) -> vec2<f32> {
    return select(vec2<f32>(-1.0), vec2<f32>(1.0), v >= vec2<f32>(0.0));
}

fn encode_normal_depth(n: vec3<f32>, depth: f32) -> vec2<u32> {
    var p = n.xy / (abs(n.x) + abs(n.y) + abs(n.z));
    if (n.z < 0.0) {
        p = (1.0 - abs(p.yx)) * sign_not_zero(p);
    }
    return vec2<u32>(pack2x16snorm(p), bitcast<u32>(depth));
}

fn decode_normal(texel: vec2<u32>) -> vec3<f32> {
    let p = unpack2x16snorm(texel.x);
    var v = vec3<f32>(p, 1.0 - abs(p.x) - abs(p.y));
    if (v.z < 0.0) {
        v = vec3<f32>((1.0 - abs(v.yx)) * sign_not_zero(v.xy), v.z);
    }
    return normalize(v);
}

fn decode_depth(texel: vec2<u32>) -> f32 {
    return bitcast<f32>(texel.y);
}
