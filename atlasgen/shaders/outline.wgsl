// Toon outlines from g-buffer discontinuities (Saito & Takahashi 1990, "Comprehensible
// Rendering of 3-D Shapes"): a pixel is an edge when the depth or the normal jumps
// between it and a 4-neighbour, and it is drawn only where the pixel or a neighbour
// belongs to a material whose manifest flags ask for outlines (ATLAS_FLAGS bit 0).
// Prepended by the generated atlas include and common.wgsl.
//
// Depth test: inverse view depth is affine in screen space across a plane, so its
// second difference is zero on any plane however steep, small on smooth curved
// surfaces, and of order 1 (relative) across a depth discontinuity.
// Normal test: dot(n_centre, n_neighbour) below cos(threshold) marks a crease.

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var normal_depth_tex: texture_2d<u32>;
@group(0) @binding(2) var material_tex: texture_2d<u32>;

fn wants_outline(material: u32) -> bool {
    return material != NO_MATERIAL && (atlas_material_flags(material) & ATLAS_FLAG_OUTLINE) != 0u;
}

struct Sample {
    material: u32,
    normal: vec3<f32>,
    inv_depth: f32,  // 0 for empty pixels: they lie at infinity
};

fn load_sample(p: vec2<i32>) -> Sample {
    let size = vec2<i32>(frame.viewport.xy);
    let q = clamp(p, vec2<i32>(0), size - 1);
    var s: Sample;
    s.material = textureLoad(material_tex, q, 0).r;
    let nd = textureLoad(normal_depth_tex, q, 0).xy;
    s.normal = decode_normal(nd);
    s.inv_depth = select(1.0 / max(decode_depth(nd), 1e-30), 0.0, s.material == NO_MATERIAL);
    return s;
}

fn depth_edge(a: Sample, c: Sample, b: Sample) -> bool {
    let second = abs(a.inv_depth + b.inv_depth - 2.0 * c.inv_depth);
    let scale = max(max(a.inv_depth, b.inv_depth), c.inv_depth);
    return scale > 0.0 && second > frame.outline.x * scale;
}

fn normal_edge(c: Sample, o: Sample) -> bool {
    return c.material != NO_MATERIAL && o.material != NO_MATERIAL && dot(c.normal, o.normal) < frame.outline.y;
}

@fragment
fn fs_main(@builtin(position) coord: vec4<f32>) -> @location(0) vec4<f32> {
    let p = vec2<i32>(coord.xy);
    let c = load_sample(p);
    let l = load_sample(p + vec2<i32>(-1, 0));
    let r = load_sample(p + vec2<i32>(1, 0));
    let d = load_sample(p + vec2<i32>(0, -1));
    let u = load_sample(p + vec2<i32>(0, 1));
    let flagged = wants_outline(c.material) || wants_outline(l.material) || wants_outline(r.material)
        || wants_outline(d.material) || wants_outline(u.material);
    let edge = depth_edge(l, c, r) || depth_edge(d, c, u)
        || normal_edge(c, l) || normal_edge(c, r) || normal_edge(c, d) || normal_edge(c, u);
    if (!(flagged && edge)) {
        discard;
    }
    return vec4<f32>(frame.outline_colour.rgb, 1.0);
}
