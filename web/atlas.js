// Load an atlasgen KTX2 atlas into three.js and sample it with the generated GLSL include.
// docs/engine-integration.md shows this file; tests/web/test_threejs.py runs it in headless Chromium.
import * as THREE from 'three';
import { read } from 'ktx-parse';

const VK_FORMAT_R8G8B8A8_SRGB = 43;

// X.ktx2 (a 2D array of 256 layers, RGBA8, every mip level) as a texture three.js uploads whole.
// A DataArrayTexture uploads level 0 alone (three.js r187 ignores its .mipmaps); the
// CompressedArrayTexture path uploads each level of .mipmaps, uncompressed RGBA8 included.
export async function loadAtlas(url) {
  const ktx = read(new Uint8Array(await (await fetch(url)).arrayBuffer()));
  if (ktx.supercompressionScheme !== 0) throw new Error(`${url}: bake without --zstd for this loader`);
  const mipmaps = ktx.levels.map((level, i) => ({
    data: level.levelData, // every layer in turn, layer 0 first
    width: Math.max(1, ktx.pixelWidth >> i),
    height: Math.max(1, ktx.pixelHeight >> i),
  }));
  const texture = new THREE.CompressedArrayTexture(
    mipmaps, ktx.pixelWidth, ktx.pixelHeight, ktx.layerCount, THREE.RGBAFormat, THREE.UnsignedByteType);
  // sRGB atlases decode in the sampler, before filtering, as the include expects.
  texture.colorSpace = ktx.vkFormat === VK_FORMAT_R8G8B8A8_SRGB ? THREE.SRGBColorSpace : THREE.NoColorSpace;
  texture.minFilter = THREE.LinearMipmapLinearFilter;
  texture.magFilter = THREE.LinearFilter;
  texture.wrapS = texture.wrapT = THREE.ClampToEdgeWrapping;
  texture.generateMipmaps = false; // the bake's mips are per material; never regenerate them
  texture.needsUpdate = true;
  return texture;
}

// The include is Vulkan GLSL 4.50, a texture and a sampler apart; WebGL2's GLSL ES 3.00 has
// combined samplers only. These macros make each texture parameter a sampler, the separate
// sampler an unused int, and sampler2DArray(tex, samp) the texture itself (sampler3D for a
// --layout volume include, whose atlas is a 3D texture).
export const GLSL_ES_PRELUDE = `precision highp float;
precision highp int;
precision highp sampler2D;
precision highp sampler2DArray;
precision highp sampler3D;
#define texture2DArray sampler2DArray
#define texture2D sampler2D
#define texture3D sampler3D
#define sampler int
#define sampler2DArray(t, s) t
#define sampler2D(t, s) t
#define sampler3D(t, s) t
`;

// A ShaderMaterial (GLSL ES 3.00) whose fragment shader is `body`, after the include X.glsl.
// RawShaderMaterial: three.js adds only #version 300 es, none of the #defines it gives a
// ShaderMaterial (one is `#define texture2D texture`, which the prelude above must own).
export function atlasMaterial(atlas, includeText, body, uniforms = {}) {
  return new THREE.RawShaderMaterial({
    glslVersion: THREE.GLSL3,
    uniforms: { atlas: { value: atlas }, ...uniforms },
    vertexShader: `in vec3 position;
void main() { gl_Position = vec4(position.xy, 0.0, 1.0); }`,
    fragmentShader: `${GLSL_ES_PRELUDE}${includeText}
uniform sampler2DArray atlas;
out vec4 fragColor;
${body}`,
  });
}

// Usage, the shading line of the docs (sampler argument: any int):
//   vec4 A = atlas_sample(atlas, 0, material, dot(n, l), dot(n, v), 0.0);
//   L += E * (albedo * A.rgb / ATLAS_PI + A.a * specular(n, l, v, specular_alpha(gloss)));
