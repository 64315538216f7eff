// tools/shader-pack.mjs - the shader files of some programs of shaders/manifest.json as one
// object, {manifest: {prefix, programs}, files: {NAME: text}}: what client/btf-shader-pack.js
// holds inside a bundle (btf-gl.js assemble() reads it as it reads the fetched files), and
// the esbuild plugin that puts it there. Used by tools/bundle.mjs and tools/npm-dist.mjs.
import fs from 'node:fs';
import path from 'node:path';
import {fileURLToPath} from 'node:url';

export const ROOT = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..');

export function shaderPack(programNames) {
  const dir = path.join(ROOT, 'shaders');
  const manifest = JSON.parse(fs.readFileSync(path.join(dir, 'manifest.json'), 'utf8'));
  const programs = {}, files = {};
  for (const name of programNames) {
    const prog = manifest.programs[name];
    if (!prog) throw new Error(`shaders/manifest.json has no program '${name}'`);
    programs[name] = prog;
    for (const f of [...prog.vertex, ...prog.fragment]) files[f] = fs.readFileSync(path.join(dir, f), 'utf8');
  }
  return {manifest: {prefix: manifest.prefix, programs}, files};
}

// esbuild: client/btf-shader-pack.js becomes the pack of these programs.
export function shaderPackPlugin(programNames) {
  return {
    name: 'shader-pack',
    setup(build) {
      build.onLoad({filter: /btf-shader-pack\.js$/}, () => ({
        contents: `export const SHADER_PACK = ${JSON.stringify(shaderPack(programNames))};\n`, loader: 'js'}));
    },
  };
}
