// Tiled light culling (Andersson 2011, "DirectX 11 Rendering in Battlefield 3"; Olsson &
// Assarsson 2011, "Tiled Shading"): for each TILE_SIZE x TILE_SIZE screen tile, the list of lights
// that can reach the tile's pixels, for the lighting pass; one workgroup takes a square of
// CULL_GROUP_TILES x CULL_GROUP_TILES tiles.
//
// 0. First, once per frame (cs_coarse), a coarse pass keeps for each COARSE_TILES x COARSE_TILES
//    block of tiles the lights not wholly outside the block's four side planes (no depths: the
//    translucent layers' culls reuse it), as a bit mask per block. Step 2 then tests only the
//    lights of its block's mask: a light the block drops cannot reach any of its pixels, since
//    every tile's frustum lies inside its block's. With many short-ranged lights a block keeps
//    few of them, and the fine pass tests only those.
// 1. Depth bounds: each of a tile's 4 x 4 invocations reads the view depth of its SPAN x SPAN
//    pixels from the g-buffer; the workgroup keeps each tile's min and max over the pixels some
//    object covers (empty pixels hold FAR_DEPTH). Positive floats order as their bits, so
//    atomicMax on the bits (and on their complement, for the min) orders the depths. The
//    workgroup's memory is cleared first: lavapipe hands the next workgroup what the last left
//    (the mask's words are each written whole in step 2).
// 2. Each light of the tile's block (step 0) is kept unless its sphere (centre in camera space,
//    range; light_spheres, filled by the CPU, atlasgen/render/culling.py pack_light_spheres)
//    lies wholly outside one of the tile's four side planes through the eye, or wholly outside the camera-space box
//    that bounds the tile's frustum between z_min and z_max. The planes alone keep a large
//    sphere near a tile's corner that misses the tile; the box, which bounds a thin tile tightly,
//    drops most of those (bench/render.py reports the lights per tile against the lights that
//    reach a pixel). Unbounded lights (range 0: directional, or no range
//    given) are always kept. Kept lights set their bit in a workgroup mask.
// 3. The mask is written out in light order, so a tile's list sums its lights in the same
//    order as the full loop: count first, then up to capacity entries, each a copy of its
//    light's first ENTRY_TEXELS texels (what shading a point light reads, and its index). The count is the
//    true number, even beyond the capacity: the lighting pass then loops over every
//    light for that tile instead (never a silently truncated list).
//
// On a software GPU every barrier costs a switch of all invocations, and a workgroup's set-up more
// than culling a tile: so there are three barriers, a sixteenth as many invocations as pixels, and
// a workgroup takes 16 tiles.

@group(0) @binding(0) var<uniform> frame: Frame;
// Per light: camera-space centre (x along right, y along up, z along forward from the eye), range (0: unbounded).
// Texel i: light i's sphere.
@group(0) @binding(1) var light_spheres: texture_2d<f32>;
@group(0) @binding(2) var normal_depth_tex: texture_2d<u32>;
// Tile (tx, ty)'s list: row tx of layer ty, the count in texel 0, then ENTRY_TEXELS texels per light
// (atlasgen/render/culling.py create_tile_texture).
@group(0) @binding(3) var tile_lights: texture_storage_2d_array<rgba32uint, write>;
@group(0) @binding(4) var<uniform> cull: Cull;
// Word w of block (bx, by)'s mask of lights: texel (w, bx) of layer by, written by cs_coarse
// (binding 6, its own bind group) and read by cs_cull (binding 5).
@group(0) @binding(5) var coarse_masks: texture_2d_array<u32>;
@group(0) @binding(6) var coarse_out: texture_storage_2d_array<r32uint, write>;
// Row i: light i's Light texels (atlasgen/render/lighting.py pack_lights); a list copies the first ENTRY_TEXELS.
@group(0) @binding(7) var light_texels: texture_2d<u32>;

// @declare Cull
// @declare TILE_SIZE
// @declare LIGHT_MASK_WORDS
// @declare COARSE_TILES
// @declare CULL_GROUP_TILES
// @declare ENTRY_TEXELS

// The sphere test is loosened by this share of the range: float32 rounding in the planes
// must never cull a light that reaches a pixel, and where it only just does, it adds ~0.
const RANGE_SLACK: f32 = 1.001;
// A workgroup culls CULL_GROUP_TILES x CULL_GROUP_TILES tiles (on a software GPU a workgroup's set-up and
// barriers cost more than its work), with CULL_GROUP x CULL_GROUP invocations, 4 x 4 to a tile, each
// reading SPAN x SPAN pixels of its tile.
const CULL_GROUP: u32 = CULL_GROUP_TILES * 4u;
const INVOCATIONS: u32 = CULL_GROUP * CULL_GROUP;
const GROUP_TILE_COUNT: u32 = CULL_GROUP_TILES * CULL_GROUP_TILES;
const SPAN: u32 = TILE_SIZE / 4u;
// Depths at or beyond this are the g-buffer's clear value (FAR_DEPTH, 3e38): no object there.
const EMPTY_DEPTH: f32 = 1.0e38;

// Per tile of the workgroup (its slot, row by row): the depth bounds and the mask of kept lights
// (cs_coarse uses the first LIGHT_MASK_WORDS words for its block's).
var<workgroup> depth_min_complement: array<atomic<u32>, GROUP_TILE_COUNT>;
var<workgroup> depth_max: array<atomic<u32>, GROUP_TILE_COUNT>;
var<workgroup> mask: array<atomic<u32>, GROUP_TILE_COUNT * LIGHT_MASK_WORDS>;

// The unit normal (in the (s, z) plane) of the plane through the eye that holds the camera's up
// (or right) axis and the screen line at slope a: dot(normal, (s, z)) = (s - a z) / sqrt(1 + a^2),
// the signed distance, positive on the side where s / z > a.
fn plane_normal(a: f32) -> vec2<f32> {
    return vec2<f32>(1.0, -a) * inverseSqrt(1.0 + a * a);
}

// The edges of the pixel rectangle [lo, hi) as camera-space slopes: x / z of its left and right
// edges, then y / z of its bottom and top ones (image y runs along -up).
fn edge_slopes(lo: vec2<f32>, hi: vec2<f32>) -> vec4<f32> {
    let ndc_lo = lo * frame.viewport.zw * 2.0 - 1.0;
    let ndc_hi = hi * frame.viewport.zw * 2.0 - 1.0;
    return vec4<f32>(vec2<f32>(ndc_lo.x, ndc_hi.x) * frame.forward.w, vec2<f32>(-ndc_hi.y, -ndc_lo.y) * frame.right.w);
}

// The four side planes through the eye and edges of those slopes: (left, right) in the (x, z)
// plane, then (top, bottom) in the (y, z) plane, each facing inwards.
struct SidePlanes {
    left: vec2<f32>,
    right: vec2<f32>,
    top: vec2<f32>,
    bottom: vec2<f32>,
}

fn side_planes(slopes: vec4<f32>) -> SidePlanes {
    return SidePlanes(plane_normal(slopes.x), -plane_normal(slopes.y), -plane_normal(slopes.w), plane_normal(slopes.z));
}

// Whether a sphere (camera-space centre, radius r) is not wholly outside any of the planes.
fn within_planes(planes: SidePlanes, centre: vec3<f32>, r: f32) -> bool {
    return dot(planes.left, centre.xz) >= -r && dot(planes.right, centre.xz) >= -r
        && dot(planes.bottom, centre.yz) >= -r && dot(planes.top, centre.yz) >= -r;
}

// Step 0: one workgroup per block of COARSE_TILES x COARSE_TILES tiles; each invocation tests every
// INVOCATIONS-th light against the block's side planes.
@compute @workgroup_size(CULL_GROUP, CULL_GROUP)
fn cs_coarse(@builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_index) index: u32) {
    for (var w = index; w < LIGHT_MASK_WORDS; w = w + INVOCATIONS) {
        atomicStore(&mask[w], 0u);
    }
    workgroupBarrier();
    let size = vec2<u32>(frame.viewport.xy);
    let lo = group.xy * (TILE_SIZE * COARSE_TILES);
    let planes = side_planes(edge_slopes(vec2<f32>(lo), vec2<f32>(min(lo + TILE_SIZE * COARSE_TILES, size))));
    for (var i = index; i < frame.counts.x; i = i + INVOCATIONS) {
        let sphere = textureLoad(light_spheres, vec2<u32>(i, 0u), 0);
        let r = sphere.w * RANGE_SLACK;
        if (sphere.w <= 0.0 || within_planes(planes, sphere.xyz, r)) {
            atomicOr(&mask[i / 32u], 1u << (i % 32u));
        }
    }
    workgroupBarrier();
    let words = (frame.counts.x + 31u) / 32u;
    for (var w = index; w < words; w = w + INVOCATIONS) {
        textureStore(coarse_out, vec2<u32>(w, group.x), group.y, vec4<u32>(atomicLoad(&mask[w])));
    }
}

@compute @workgroup_size(CULL_GROUP, CULL_GROUP)
fn cs_cull(@builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_id) local: vec3<u32>,
           @builtin(local_invocation_index) index: u32) {
    if (index < GROUP_TILE_COUNT) {
        atomicStore(&depth_min_complement[index], 0u);
        atomicStore(&depth_max[index], 0u);
    }
    workgroupBarrier();
    let size = vec2<u32>(frame.viewport.xy);
    // The workgroup's first tile, and one past the last tile of the rectangle this dispatch culls.
    let first = cull.origin.xy + group.xy * CULL_GROUP_TILES;
    let end = cull.origin.zw;
    // The invocation's SPAN x SPAN pixels, all in one tile of the workgroup's: its slot.
    let corner = first * TILE_SIZE + local.xy * SPAN;
    let own = local.xy / (CULL_GROUP / CULL_GROUP_TILES);
    var lo_bits = 0xffffffffu;
    var hi_bits = 0u;
    for (var k = 0u; k < SPAN * SPAN; k = k + 1u) {
        let pixel = corner + vec2<u32>(k % SPAN, k / SPAN);
        if (all(pixel < size)) {
            let depth = decode_depth(textureLoad(normal_depth_tex, vec2<i32>(pixel), 0).xy);
            if (depth < EMPTY_DEPTH) {
                lo_bits = min(lo_bits, bitcast<u32>(depth));
                hi_bits = max(hi_bits, bitcast<u32>(depth));
            }
        }
    }
    if (hi_bits != 0u) {
        let slot = own.y * CULL_GROUP_TILES + own.x;
        atomicMax(&depth_min_complement[slot], ~lo_bits);
        atomicMax(&depth_max[slot], hi_bits);
    }
    workgroupBarrier();

    // Each invocation takes whole words of a tile's mask (no two write one word): only the tile's
    // block's lights are tested.
    let words = (frame.counts.x + 31u) / 32u;
    for (var item = index; item < GROUP_TILE_COUNT * words; item = item + INVOCATIONS) {
        let slot = item / words;
        let w = item % words;
        let tile = first + vec2<u32>(slot % CULL_GROUP_TILES, slot / CULL_GROUP_TILES);
        let z_min = bitcast<f32>(~atomicLoad(&depth_min_complement[slot]));
        let z_max = bitcast<f32>(atomicLoad(&depth_max[slot]));
        let covered = atomicLoad(&depth_max[slot]) != 0u && all(tile < end);

        let slopes = edge_slopes(vec2<f32>(tile * TILE_SIZE), vec2<f32>(min((tile + 1u) * TILE_SIZE, size)));
        let planes = side_planes(slopes);
        // x = a z over the tile's slopes a and z in [z_min, z_max]: the box holds the four edges' ends.
        let slope_x = slopes.xy;
        let slope_y = slopes.zw;
        let near_x = slope_x * z_min;
        let far_x = slope_x * z_max;
        let near_y = slope_y * z_min;
        let far_y = slope_y * z_max;
        let box_lo = vec3<f32>(min(near_x.x, far_x.x), min(near_y.x, far_y.x), z_min);
        let box_hi = vec3<f32>(max(near_x.y, far_x.y), max(near_y.y, far_y.y), z_max);

        let block = tile / COARSE_TILES;
        var bits = select(0u, textureLoad(coarse_masks, vec2<u32>(w, block.x), block.y, 0).r, covered);
        var kept = 0u;
        loop {
            if (bits == 0u) {
                break;
            }
            let b = firstTrailingBit(bits);
            bits = bits & (bits - 1u);
            let sphere = textureLoad(light_spheres, vec2<u32>(w * 32u + b, 0u), 0);
            var keep = true;
            if (sphere.w > 0.0) {
                let r = sphere.w * RANGE_SLACK;
                let gap = sphere.xyz - clamp(sphere.xyz, box_lo, box_hi);
                keep = dot(gap, gap) <= r * r && within_planes(planes, sphere.xyz, r);
            }
            if (keep) {
                kept = kept | (1u << b);
            }
        }
        atomicStore(&mask[slot * LIGHT_MASK_WORDS + w], kept);
    }
    workgroupBarrier();
    // Each invocation writes the lights of its words, after those of its tile's words before them.
    let capacity = frame.counts.w;
    var offset = 0u;
    var counted = 0u;
    var counting = GROUP_TILE_COUNT;
    for (var item = index; item < GROUP_TILE_COUNT * words; item = item + INVOCATIONS) {
        let slot = item / words;
        let w = item % words;
        let tile = first + vec2<u32>(slot % CULL_GROUP_TILES, slot / CULL_GROUP_TILES);
        if (slot != counting) {
            counting = slot;
            offset = 0u;
            counted = 0u;
        }
        for (; counted < w; counted = counted + 1u) {
            offset = offset + countOneBits(atomicLoad(&mask[slot * LIGHT_MASK_WORDS + counted]));
        }
        var bits = atomicLoad(&mask[slot * LIGHT_MASK_WORDS + w]);
        counted = w + 1u;
        let inside = all(tile < end);
        loop {
            if (bits == 0u) {
                break;
            }
            if (offset < capacity && inside) {
                let light = w * 32u + firstTrailingBit(bits);
                for (var i = 0u; i < ENTRY_TEXELS; i = i + 1u) {
                    let texel = textureLoad(light_texels, vec2<u32>(i, light), 0);
                    textureStore(tile_lights, vec2<u32>(1u + offset * ENTRY_TEXELS + i, tile.x), tile.y, texel);
                }
            }
            offset = offset + 1u;
            bits = bits & (bits - 1u);
        }
        if (w == words - 1u && inside) {
            textureStore(tile_lights, vec2<u32>(0u, tile.x), tile.y, vec4<u32>(offset));
        }
    }
    if (words == 0u && index < GROUP_TILE_COUNT) {
        let tile = first + vec2<u32>(index % CULL_GROUP_TILES, index / CULL_GROUP_TILES);
        if (all(tile < end)) {
            textureStore(tile_lights, vec2<u32>(0u, tile.x), tile.y, vec4<u32>(0u));
        }
    }
}
