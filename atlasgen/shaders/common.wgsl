// atlasgen renderer: declarations shared by every pass.
//
// Radiometric units follow Mitsuba 3 exactly (docs/scenes.md): radiance in W/(m^2 sr),
// point lights are radiant intensities I (irradiance I / d^2), directional lights are
// irradiances E normal to their direction.

struct Frame {
    view_proj: mat4x4<f32>,
    eye: vec4<f32>,            // camera position; w unused
    forward: vec4<f32>,        // unit view direction; w = tan(horizontal half field of view)
    right: vec4<f32>,          // unit image-x direction; w = tan(vertical half field of view)
    up: vec4<f32>,             // unit image-up direction (image y runs along -up)
    viewport: vec4<f32>,       // width, height, 1 / width, 1 / height
    background: vec4<f32>,     // radiance of pixels no object covers
    mip: vec4<f32>,            // x: bias, y: reference distance, z: last mip level
    counts: vec4<u32>,         // x: number of lights
    outline_colour: vec4<f32>, // radiance written on outline pixels
    outline: vec4<f32>,        // x: relative inverse-depth threshold, y: cos(normal threshold)
};

// Material-ID target value of pixels that no object covers (cleared, never written).
const NO_MATERIAL: u32 = 0xFFFFu;
const PI: f32 = 3.14159265358979;

// One triangle covering the viewport: no vertex buffer needed.
@vertex
fn vs_fullscreen(@builtin(vertex_index) index: u32) -> @builtin(position) vec4<f32> {
    let xy = vec2<f32>(f32((index << 1u) & 2u), f32(index & 2u));
    return vec4<f32>(xy * 2.0 - 1.0, 0.0, 1.0);
}
