// Debugging aid: writes 1 wherever the pipeline's stencil test passes, so the stencil
// marks of deferred translucency can be read back (WebGPU cannot copy a stencil
// aspect through every binding). Prepended by common.wgsl for vs_fullscreen.

@fragment
fn fs_main() -> @location(0) vec4<f32> {
    return vec4<f32>(1.0, 0.0, 0.0, 1.0);
}
