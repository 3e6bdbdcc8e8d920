// G-buffer pass: one draw per object writes albedo + gloss, normal + view depth and
// the material ID. Depth-stencil state (z-writes, stencil marking of translucent
// objects) is set by the pipeline, not here. Prepended by common.wgsl.

// @declare Object

@group(0) @binding(0) var<uniform> frame: Frame;
@group(1) @binding(0) var<uniform> object: Object;

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
};

@vertex
fn vs_main(@location(0) position: vec3<f32>, @location(1) normal: vec3<f32>) -> VertexOut {
    let world = object.model * vec4<f32>(position, 1.0);
    var out: VertexOut;
    out.clip = frame.view_proj * world;
    out.world = world.xyz;
    out.normal = (object.normal_matrix * vec4<f32>(normal, 0.0)).xyz;
    return out;
}

struct GBufferOut {
    @location(0) albedo_gloss: vec4<f32>,
    @location(1) normal_depth: vec2<u32>,  // world-space unit normal, view depth along forward (encode_normal_depth)
    @location(2) material: u32,
};

// v over its largest component: the same direction at a length in [1, sqrt 3], so that dot(v, v) neither
// overflows nor underflows. An object scaled by 1e11 has normals of length 1e-11 through its normal
// matrix and faces of area 1e22 a pixel, and one flattened by 1e-30 normals of 1e30: the squares
// passed float32's range, and every pixel got the zero vector's fallback normal.
fn rescaled(v: vec3<f32>) -> vec3<f32> {
    let m = max(max(abs(v.x), abs(v.y)), abs(v.z));
    return select(v, v / m, m > 0.0);
}

@fragment
fn fs_main(in: VertexOut, @builtin(front_facing) front: bool) -> GBufferOut {
    // Derivatives must be taken in uniform control flow, so before any branch.
    let face = cross(rescaled(dpdx(in.world)), rescaled(dpdy(in.world)));
    let to_eye = frame.eye.xyz - in.world;
    var n = rescaled(in.normal);
    let len2 = dot(n, n);
    if (len2 > 1e-20) {
        n = n * inverseSqrt(len2);
        // Two-sided: a back face (a plane seen from below) is shaded with the flipped normal.
        if (!front) {
            n = -n;
        }
    } else {
        // Zero (or NaN) interpolated normals come from degenerate input: fall back to
        // the face normal, and to the view direction when even that is degenerate.
        let flen2 = dot(face, face);
        if (flen2 > 1e-30) {
            n = face * inverseSqrt(flen2);
            if (dot(n, to_eye) < 0.0) {
                n = -n;
            }
        } else {
            n = normalize(to_eye);
        }
    }
    var out: GBufferOut;
    out.albedo_gloss = object.albedo_gloss;
    out.normal_depth = encode_normal_depth(n, dot(in.world - frame.eye.xyz, frame.forward.xyz));
    out.material = object.material.x;
    return out;
}
