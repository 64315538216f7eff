// btf-shader-pack.js - the shader files inside the script. In the source tree nothing
// (the viewer fetches shaders/ next to its script); the bundle (tools/bundle.mjs)
// replaces this module with the manifest entries and files of the programs "render"
// and "flat" (a model's unbound parts), read from shaders/ at build time:
// {manifest: {prefix, programs: {render, flat}}, files: {NAME: text}}.
export const SHADER_PACK = null;
