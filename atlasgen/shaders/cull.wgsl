// Tiled light culling (Andersson 2011, "DirectX 11 Rendering in Battlefield 3"; Olsson &
// Assarsson 2011, "Tiled Shading"): one workgroup per TILE_SIZE x TILE_SIZE screen tile
// builds the list of lights that can reach the tile's pixels, for the lighting pass.
//
// 1. Depth bounds: every invocation reads its pixel's view depth from the g-buffer; the
//    workgroup keeps the min and max over the pixels some object covers (positive floats
//    order as their bits, so atomicMin/atomicMax on the bits order the depths).
// 2. Each light's sphere (centre, range) is tested against the tile's four side planes
//    through the eye and the depth range [z_min, z_max]: it is kept unless it lies wholly
//    outside one of them. Unbounded lights (range 0: directional, or no range given) are
//    always kept. Kept lights set their bit in a workgroup mask.
// 3. The mask is written out in light order, so a tile's list sums its lights in the same
//    order as the full loop: count first, then up to capacity indices. The count is the
//    true number, even beyond the capacity: the lighting pass then loops over every
//    light for that tile instead (never a silently truncated list).

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<storage, read> lights: array<Light>;
@group(0) @binding(2) var normal_depth_tex: texture_2d<f32>;
@group(0) @binding(3) var material_tex: texture_2d<u32>;
@group(0) @binding(4) var<storage, read_write> tile_lights: array<u32>;
@group(0) @binding(5) var<uniform> cull: Cull;

// @declare Light
// @declare Cull
// @declare TILE_SIZE
// @declare LIGHT_MASK_WORDS

// The sphere test is loosened by this share of the range: float32 rounding in the planes
// must never cull a light that reaches a pixel, and where it only just does, it adds ~0.
const RANGE_SLACK: f32 = 1.001;

var<workgroup> depth_min: atomic<u32>;
var<workgroup> depth_max: atomic<u32>;
var<workgroup> mask: array<atomic<u32>, LIGHT_MASK_WORDS>;
var<workgroup> word_count: array<u32, LIGHT_MASK_WORDS>;

// Signed distance from the plane through the eye that holds the camera's up (or right) axis
// and the screen line at slope a: points p with s - a z >= 0 lie on the inner side.
fn plane_distance(s: f32, z: f32, a: f32) -> f32 {
    return (s - a * z) * inverseSqrt(1.0 + a * a);
}

@compute @workgroup_size(TILE_SIZE, TILE_SIZE)
fn cs_cull(@builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_id) local: vec3<u32>,
           @builtin(local_invocation_index) index: u32) {
    let tile = cull.origin.xy + group.xy;
    if (index == 0u) {
        atomicStore(&depth_min, 0x7f7fffffu);
        atomicStore(&depth_max, 0u);
    }
    for (var w = index; w < LIGHT_MASK_WORDS; w = w + TILE_SIZE * TILE_SIZE) {
        atomicStore(&mask[w], 0u);
    }
    workgroupBarrier();

    let size = vec2<u32>(frame.viewport.xy);
    let pixel = tile * TILE_SIZE + local.xy;
    if (all(pixel < size)) {
        if (textureLoad(material_tex, vec2<i32>(pixel), 0).r != NO_MATERIAL) {
            let bits = bitcast<u32>(textureLoad(normal_depth_tex, vec2<i32>(pixel), 0).w);
            atomicMin(&depth_min, bits);
            atomicMax(&depth_max, bits);
        }
    }
    workgroupBarrier();
    let z_min = bitcast<f32>(atomicLoad(&depth_min));
    let z_max = bitcast<f32>(atomicLoad(&depth_max));
    let covered = atomicLoad(&depth_max) != 0u;

    // The tile's edges as slopes: camera-space x / z from its left and right pixel edges,
    // y / z from its top and bottom ones (image y runs along -up).
    let lo = vec2<f32>(tile * TILE_SIZE);
    let hi = vec2<f32>(min((tile + 1u) * TILE_SIZE, size));
    let ndc_lo = lo * frame.viewport.zw * 2.0 - 1.0;
    let ndc_hi = hi * frame.viewport.zw * 2.0 - 1.0;
    let left = ndc_lo.x * frame.forward.w;
    let right = ndc_hi.x * frame.forward.w;
    let top = -ndc_lo.y * frame.right.w;
    let bottom = -ndc_hi.y * frame.right.w;

    for (var i = index; i < frame.counts.x; i = i + TILE_SIZE * TILE_SIZE) {
        let light = lights[i];
        var keep = covered;
        if (covered && light.range > 0.0) {
            let c = light.position - frame.eye.xyz;
            let x = dot(c, frame.right.xyz);
            let y = dot(c, frame.up.xyz);
            let z = dot(c, frame.forward.xyz);
            let r = light.range * RANGE_SLACK;
            keep = z + r >= z_min && z - r <= z_max
                && plane_distance(x, z, left) >= -r && -plane_distance(x, z, right) >= -r
                && plane_distance(y, z, bottom) >= -r && -plane_distance(y, z, top) >= -r;
        }
        if (keep) {
            atomicOr(&mask[i / 32u], 1u << (i % 32u));
        }
    }
    workgroupBarrier();
    if (index < LIGHT_MASK_WORDS) {
        word_count[index] = countOneBits(atomicLoad(&mask[index]));
    }
    workgroupBarrier();
    if (index < LIGHT_MASK_WORDS) {
        let capacity = frame.counts.w;
        let base = (tile.y * frame.counts.z + tile.x) * (capacity + 1u);
        var offset = 0u;
        for (var k = 0u; k < index; k = k + 1u) {
            offset = offset + word_count[k];
        }
        var bits = atomicLoad(&mask[index]);
        loop {
            if (bits == 0u) {
                break;
            }
            if (offset < capacity) {
                tile_lights[base + 1u + offset] = index * 32u + firstTrailingBit(bits);
            }
            offset = offset + 1u;
            bits = bits & (bits - 1u);
        }
        if (index == LIGHT_MASK_WORDS - 1u) {
            tile_lights[base] = offset;
        }
    }
}
