// Deferred lighting: one full-screen pass loops over the lights of each pixel's tile (the
// lists cull.wgsl built), or over every light where the frame has no lists or the tile's
// list overflowed.
// Prepended by the generated atlas include (atlas_sample, ATLAS_* tables, and the code
// models add, e.g. separable_f_cos_NAME), the renderer's material_has_shader and
// material_f_cos switches (generated from the manifest and the models' lighting_wgsl)
// and common.wgsl.
//
// Per light, with E the irradiance normal to the light direction at the surface (light_at):
//
//     L += E * (albedo * A.rgb / pi + A.a * specular(n, l, v, alpha))
//
// A = atlas_sample(material, N.L, N.V, lod) is the material's slice with its scale and
// bias applied. A.rgb already holds the cosine fall-off (a lambert slice stores
// colour * max(N.L, 0)), so albedo * A.rgb / pi is a Lambertian BRDF times cos and
// the 1/pi lives here, in the renderer. specular is a BRDF times cos as well: the GGX
// lobe D(N.H) V(N.L, N.V) N.L with height-correlated Smith visibility and
// alpha = max((1 - gloss)^2, 0.002) (docs/atlas-format.md, "The shading equation").
//
// Materials whose model shades them itself return f cos from material_f_cos, in 1/sr
// (separable BRDFs rebuild it from their factors at mip level 0, Kautz & McCool 1999):
// L += E * albedo * f cos.

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(2) var albedo_gloss_tex: texture_2d<f32>;
@group(0) @binding(3) var normal_depth_tex: texture_2d<u32>;
@group(0) @binding(4) var material_tex: texture_2d<u32>;
@group(0) @binding(5) var atlas: texture_2d_array<f32>;
@group(0) @binding(6) var atlas_sampler: sampler;
@group(0) @binding(7) var<uniform> env: Environment;
@group(0) @binding(8) var env_tex: texture_2d<f32>;
@group(0) @binding(9) var env_sampler: sampler;
@group(0) @binding(10) var env_tables: texture_2d_array<f32>;
@group(0) @binding(11) var tile_lights: texture_2d_array<u32>;

// @declare Environment

// Environment lighting (docs/atlas-format.md, "Environment lighting"), before the light loop:
//
//     table material:     L += albedo * atlas_sh_diffuse(n, sh, lambda(N.V)) + Lpre(r, alpha) * S(N.V, gloss)
//     separable material: L += albedo * Lpre(r, alpha) * S_sep(N.V)
//
// ENVIRONMENT_LIGHTING is a constant the renderer prepends (atlasgen/render/lighting.py): a scene
// without an environment compiles these branches out. env_tables holds each slice's lambda_l
// (texels 0..4), S at 16 glosses (texels 5..8, four a texel) and S_sep (texel 9) per N.V row
// (atlasgen/render/environment.py); rgba32float is not filterable, so rows are blended here.

fn env_row(nv: f32, nearest: bool) -> vec2<f32> {
    // (row j0, weight of row j0 + 1) at N.V, row j at N.V = j / 31 as the atlas's rows.
    let y = clamp(nv, 0.0, 1.0) * f32(ATLAS_HEIGHT - 1u);
    var j0 = min(floor(y), f32(ATLAS_HEIGHT - 2u));
    var t = y - j0;
    if (nearest) {
        t = select(0.0, 1.0, t >= 0.5);
    }
    return vec2<f32>(j0, t);
}

fn env_texel(material: u32, column: u32, row: vec2<f32>) -> vec4<f32> {
    let j0 = i32(row.x);
    let a = textureLoad(env_tables, vec2<i32>(i32(column), j0), i32(material), 0);
    let b = textureLoad(env_tables, vec2<i32>(i32(column), j0 + 1), i32(material), 0);
    return mix(a, b, row.y);
}

fn env_specular_table(material: u32, gloss: f32, row: vec2<f32>) -> f32 {
    let g = clamp(gloss, 0.0, 1.0) * 15.0;
    let i0 = u32(min(floor(g), 14.0));
    let i1 = i0 + 1u;
    let s0 = env_texel(material, 5u + i0 / 4u, row)[i0 % 4u];
    let s1 = env_texel(material, 5u + i1 / 4u, row)[i1 % 4u];
    return mix(s0, s1, g - f32(i0));
}

fn env_prefiltered(r: vec3<f32>, gloss: f32) -> vec3<f32> {
    let levels = env.params.x;
    return atlas_env_prefiltered(env_tex, env_sampler, r, atlas_env_level(gloss, levels), env.params.y, levels);
}

fn environment_radiance(material: u32, custom: bool, n: vec3<f32>, v: vec3<f32>, n_dot_v: f32,
                        albedo: vec3<f32>, gloss: f32) -> vec3<f32> {
    let r = 2.0 * dot(n, v) * n - v;
    let nearest = (atlas_material_flags(material) & ATLAS_FLAG_NEAREST) != 0u;
    let row = env_row(n_dot_v, nearest && !custom);
    let pre = env_prefiltered(r, gloss);
    if (custom) {
        return albedo * pre * env_texel(material, 9u, row).rgb;
    }
    var lam: array<vec4<f32>, 5>;
    for (var l = 0u; l < 5u; l = l + 1u) {
        lam[l] = env_texel(material, l, row);
    }
    return albedo * atlas_sh_diffuse(n, env.sh, lam) + pre * env_specular_table(material, gloss, row);
}

// @declare Light
// @declare LightType
// @declare TILE_SIZE
// @declare LIGHT_TEXELS
// @declare ENTRY_TEXELS
// @declare DISTANCE_SQUARED_FLOOR

// Texel i of the k-th light of the pixel's tile list (listed), or else of the scene's light k. Tile (tx, ty)'s
// list is row tx of layer ty: its count, then ENTRY_TEXELS texels per light, copies of the light's first ones;
// every light's own texels follow each other along the rows of the layer frame.lists.x, 2^frame.lists.y texels
// to a row (atlasgen/render/culling.py create_tile_texture). Both addresses are computed and one texel is
// fetched: lavapipe would run both fetches of an if.
fn light_texel(k: u32, i: u32, listed: bool, tile: vec2<u32>) -> vec4<u32> {
    let p = k * LIGHT_TEXELS + i;
    let own = vec3<u32>(p & ((1u << frame.lists.y) - 1u), p >> frame.lists.y, frame.lists.x);
    let entry = vec3<u32>(1u + k * ENTRY_TEXELS + i, tile.x, tile.y);
    let at = select(own, entry, listed);
    return textureLoad(tile_lights, at.xy, at.z, 0);
}

// read_light(k, listed, tile): the k-th light of the tile's list, or the scene's light k (generated from
// the Light struct, atlasgen/render/layout.py): the texels an entry copies from the list, the rest from
// the light's own row through its index (compiled out where nothing reads them, as in a scene of point lights).
// @declare read_light

// What a light sends to a surface point: the unit direction l towards it and the irradiance
// E normal to l; reaches is false where it sends nothing (beyond its range or outer cone).
struct LightSample {
    l: vec3<f32>,
    irradiance: vec3<f32>,
    reaches: bool,
}

// E = I W(d, r) S / d^2 for point and spot lights, with the range window
// W = saturate(1 - (d/r)^4)^2 (Lagarde & de Rousiers 2014; Karis 2013; 1 without a range) and,
// for a spot light, S = clamp((outer - theta) / (outer - inner), 0, 1), 0 beyond the outer cone
// (Mitsuba's spot); E as given for a directional light. atlasgen/optics/falloff.py is the NumPy form.
// lavapipe runs both sides of every branch and gathers each member it reads per pixel, so a point
// light is read and windowed without branches (x = 0 without a range gives W = 1 exactly), and the
// directional and spot code is compiled in only for scenes that have such lights (DIRECTIONAL_LIGHTS,
// SPOT_LIGHTS: constants the renderer prepends, atlasgen/render/lighting.py).
fn light_at(k: u32, listed: bool, tile: vec2<u32>, world: vec3<f32>) -> LightSample {
    let light = read_light(k, listed, tile);
    let d = light.position - world;
    // d^2 is held above float32's least normal number (falloff.py's DISTANCE_SQUARED_FLOOR) for 1/d^2 alone. The
    // window takes (d/r)^2 and the direction d over its largest component, each at the true distance: a floor of
    // 1e-12 in them (and in 1/d^2) left a scene smaller than 1e-6 black, every point out of its lights' reach. As
    // gbuffer.wgsl's rescaled, neither d^2 nor r^2 is formed where it could underflow.
    let d2 = max(dot(d, d), DISTANCE_SQUARED_FLOOR);
    let range = light.range;
    let q = d / select(1.0, range, range > 0.0);
    let x = select(0.0, dot(q, q), range > 0.0);
    let w = 1.0 - x * x;
    let m = max(max(abs(d.x), abs(d.y)), abs(d.z));
    let u = d / select(1.0, m, m > 0.0);
    // I / d^2 held within float32: a bright light just behind a surface overflowed it, and inf x 0 (the surface
    // faces away) made the pixel NaN, written as black over the other lights.
    var out = LightSample(u * inverseSqrt(max(dot(u, u), 1.0)), min(light.radiant / d2, vec3<f32>(FLOAT32_MAX)) * (w * w),
                          x < 1.0);
    if (DIRECTIONAL_LIGHTS || SPOT_LIGHTS) {
        let kind = light.kind;
        if (DIRECTIONAL_LIGHTS && kind == LIGHT_DIRECTIONAL) {
            out = LightSample(-light.direction, light.radiant, true);
        }
        if (SPOT_LIGHTS && kind == LIGHT_SPOT) {
            let cos_theta = dot(-out.l, light.direction);
            let cone = light.cone;
            let s = clamp((cone.x - acos(clamp(cos_theta, -1.0, 1.0))) * cone.y, 0.0, 1.0);
            out.irradiance = out.irradiance * s;
            out.reaches = out.reaches && cos_theta > light.cos_outer;
        }
    }
    return out;
}

// The first light from the k-th of the pixel's list on that reaches it, k moved past it; reaches is false
// when none is left. A do-while (see fs_main): it reads one entry even of an empty list, with reaches false.
fn next_light(k: ptr<function, u32>, count: u32, listed: bool, tile: vec2<u32>, world: vec3<f32>) -> LightSample {
    var arrival: LightSample;
    loop {
        arrival = light_at(*k, listed, tile, world);
        arrival.reaches = arrival.reaches && *k < count;
        *k = *k + 1u;
        if (arrival.reaches || *k >= count) {
            break;
        }
    }
    return arrival;
}

// The largest finite float32.
const FLOAT32_MAX: f32 = 3.4028234e38;

// specular_alpha and specular come with the include (generated by
// atlasgen/shaders/specular.py from the lobe of atlasgen/optics/specular.py).

// Mip level from view depth, as the talk suggests: level 0 up to the reference
// distance, one level more per doubling of depth beyond it, then the bias.
fn atlas_lod(depth: f32) -> f32 {
    let reference = frame.mip.y;
    return clamp(log2(max(depth, reference) / reference) + frame.mip.x, 0.0, frame.mip.z);
}

@fragment
fn fs_main(@builtin(position) coord: vec4<f32>) -> @location(0) vec4<f32> {
    let pixel = vec2<i32>(coord.xy);
    let material = textureLoad(material_tex, pixel, 0).r;
    if (material == NO_MATERIAL) {
        if (ENVIRONMENT_LIGHTING && env.params.z > 0.5) {
            // The environment along the pixel's ray, level 0 (the image itself).
            let ndc0 = coord.xy * frame.viewport.zw * 2.0 - 1.0;
            let ray0 = frame.forward.xyz + ndc0.x * frame.forward.w * frame.right.xyz - ndc0.y * frame.right.w * frame.up.xyz;
            let d = normalize(ray0);
            return vec4<f32>(textureSampleLevel(env_tex, env_sampler, atlas_env_uv(d, env.params.y), 0.0).rgb, 1.0);
        }
        return vec4<f32>(frame.background.rgb, 1.0);
    }
    let albedo_gloss = textureLoad(albedo_gloss_tex, pixel, 0);
    let normal_depth = textureLoad(normal_depth_tex, pixel, 0).xy;
    let n = decode_normal(normal_depth);
    let depth = decode_depth(normal_depth);

    // The pixel's ray has unit length along forward, so eye + ray * depth is the surface.
    let ndc = coord.xy * frame.viewport.zw * 2.0 - 1.0;
    let ray = frame.forward.xyz + ndc.x * frame.forward.w * frame.right.xyz - ndc.y * frame.right.w * frame.up.xyz;
    let world = frame.eye.xyz + ray * depth;
    let v = normalize(-ray);
    let n_dot_v = dot(n, v);
    let lod = atlas_lod(depth);
    let custom = material_has_shader(material);
    let alpha = specular_alpha(albedo_gloss.a);

    var radiance = vec3<f32>(0.0);
    if (ENVIRONMENT_LIGHTING) {
        radiance += environment_radiance(material, custom, n, v, n_dot_v, albedo_gloss.rgb, albedo_gloss.a);
    }
    // The tile's list (count, then indices), unless the frame has none or the list overflowed.
    var count = frame.counts.x;
    let tile = vec2<u32>(pixel) / TILE_SIZE;
    var listed = false;
    if (frame.counts.y != 0u) {
        let listed_count = textureLoad(tile_lights, vec2<u32>(0u, tile.x), tile.y, 0).x;
        if (listed_count <= frame.counts.w) {
            count = listed_count;
            listed = true;
        }
    }
    // The material is the same for every light of the pixel: a material its model shades itself loops apart
    // (a software GPU would run both branches per light), and the slice's scale, bias and nearest flag are
    // read once, not per light. The loops test at their end (do-while): lavapipe runs a loop's body, texture
    // sample included, once more after a test at its top has sent every invocation out. And they step from
    // one reaching light to the next (next_light), so the sample runs as often as the most lights that reach
    // one pixel of a SIMD block, not once per entry of the tile's list; the sums keep the list's order.
    if (custom) {
        var k = 0u;
        var arrival = next_light(&k, count, listed, tile, world);
        loop {
            if (arrival.reaches) {
                // The model's own code returns f cos in 1/sr (a factored BRDF): no 1/pi here.
                radiance += arrival.irradiance * albedo_gloss.rgb * material_f_cos(atlas, atlas_sampler, material, n, arrival.l, v);
            }
            arrival = next_light(&k, count, listed, tile, world);
            if (!arrival.reaches) {
                break;
            }
        }
    } else {
        let sb = atlas_scale_bias(material);
        let nearest = (atlas_material_flags(material) & ATLAS_FLAG_NEAREST) != 0u;
        var k = 0u;
        var arrival = next_light(&k, count, listed, tile, world);
        loop {
            if (arrival.reaches) {
                let l = arrival.l;
                let a = atlas_sample_fetched(atlas, atlas_sampler, material, dot(n, l), n_dot_v, lod, nearest, sb);
                radiance += arrival.irradiance * (albedo_gloss.rgb * a.rgb / ATLAS_PI + a.a * specular(n, l, v, alpha));
            }
            arrival = next_light(&k, count, listed, tile, world);
            if (!arrival.reaches) {
                break;
            }
        }
    }
    return vec4<f32>(radiance, 1.0);
}
