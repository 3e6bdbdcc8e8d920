// Deferred lighting: one full-screen pass loops over every light for each pixel.
// Prepended by the generated atlas include (atlas_sample, ATLAS_* tables, and the code
// models add, e.g. separable_f_cos_NAME), the renderer's material_has_shader and
// material_f_cos switches (generated from the manifest and the models' lighting_wgsl)
// and common.wgsl.
//
// Per light, with E the irradiance normal to the light direction at the surface:
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
@group(0) @binding(1) var<storage, read> lights: array<Light>;
@group(0) @binding(2) var albedo_gloss_tex: texture_2d<f32>;
@group(0) @binding(3) var normal_depth_tex: texture_2d<f32>;
@group(0) @binding(4) var material_tex: texture_2d<u32>;
@group(0) @binding(5) var atlas: texture_2d_array<f32>;
@group(0) @binding(6) var atlas_sampler: sampler;

// @declare Light
// @declare LightType

// specular_alpha and specular come with the include (generated from
// atlasgen/optics/specular.py).

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
        return vec4<f32>(frame.background.rgb, 1.0);
    }
    let albedo_gloss = textureLoad(albedo_gloss_tex, pixel, 0);
    let normal_depth = textureLoad(normal_depth_tex, pixel, 0);
    let n = normal_depth.xyz;
    let depth = normal_depth.w;

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
    for (var i = 0u; i < frame.counts.x; i = i + 1u) {
        let light = lights[i];
        var l = -light.position;
        var irradiance = light.radiant;
        if (light.kind == LIGHT_POINT) {
            let d = light.position - world;
            let d2 = max(dot(d, d), 1e-12);
            l = d * inverseSqrt(d2);
            irradiance = irradiance / d2;
        }
        if (custom) {
            // The model's own code returns f cos in 1/sr (a factored BRDF): no 1/pi here.
            radiance += irradiance * albedo_gloss.rgb * material_f_cos(atlas, atlas_sampler, material, n, l, v);
        } else {
            let a = atlas_sample(atlas, atlas_sampler, material, dot(n, l), n_dot_v, lod);
            radiance += irradiance * (albedo_gloss.rgb * a.rgb / PI + a.a * specular(n, l, v, alpha));
        }
    }
    return vec4<f32>(radiance, 1.0);
}
