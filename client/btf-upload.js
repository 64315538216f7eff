// btf-upload.js - the chunks of one subscription into one GPU package, in order: each
// decoded off the main thread (btf-decode.js: its image files; btf-package.js: its
// weights), queued, and uploaded by the next frame (btf-session.js drives it).
import {GpuPackage} from './btf-gl.js';
import {decodeImage, imageType} from './btf-decode.js';
import {checkWeightsWebp, decodeWeights, dequantWeights8, dequantWeightsW, weights8Webp} from './btf-package.js';

// Owned by a session; one per GPU package (made for a manifest, again after a context
// restore), dropped with it (free()).
export class ChunkUploads {
  // sub: the subscription (btf-stream.js) whose chunks go in; on.decoded(): a chunk waits
  // for the upload; on.fail(e): a chunk could not be decoded.
  constructor(gl, pkg, sub, capacity, on) {
    this.gpu = new GpuPackage(gl, pkg, capacity);
    this.pkg = pkg;
    this.sub = sub;
    this.on = on;
    this.chain = Promise.resolve();
    this.ready = [];  // decoded chunks in order, waiting for the upload
    this.next = 0;    // the first chunk not queued for decoding yet
    this.freed = false;
  }

  free() {
    this.freed = true;
    this.ready = [];
    this.gpu.free();
  }

  // Queues the decode of every held chunk below `limit` not queued yet: the subscription
  // may hold more (a larger budget of another viewer, the browser cache).
  pump(limit) {
    for (; this.next < limit && this.sub.chunks[this.next]; this.next++) {
      const j = this.next;
      this.chain = this.chain.then(() => this.decode(j)).catch((e) => this.on.fail(e));
    }
  }

  // Decodes chunk j (a texture is a PNG or, versions 3 and 4, a WebP, lossless or lossy,
  // or a lossy AVIF: doc/package-format.md) and queues it.
  async decode(j) {
    if (this.freed || j < this.gpu.uploaded) return;
    const chunk = this.pkg.chunks[j], files = this.sub.chunks[j];
    const data = (name) => files[chunk.files.indexOf(name)];
    const img = await this.image(chunk.tex, data);
    if (this.freed) return;
    const wt = await this.weights(chunk, data);
    if (this.freed) return;
    this.ready.push({j, img, wt});
    this.on.decoded();
  }

  // Image file `name` of a chunk decoded (btf-decode.js; alpha: keep the file's alpha); one
  // the browser cannot decode (an AVIF where it has no AVIF decoder, a damaged file) fails
  // naming the package and file.
  image(name, data, alpha = false) {
    return decodeImage(data(name), imageType(name), alpha).catch((e) => {
      throw new Error(`package ${this.pkg.name}: ${name}: ${e && e.message ? e.message : e}`);
    });
  }

  // A weights WebP `name` of a chunk (wt-JJ.webp or wt-JJ-8.webp, lossless or lossy): its
  // bytes checked as the C reader checks them (checkWeightsWebp), then decoded with its
  // alpha kept (a lossy file decodes opaque).
  weightsImage(chunk, name, data) {
    checkWeightsWebp(this.pkg, chunk, data(name), name);
    return this.image(name, data, true);
  }

  // Dequantised weights of a chunk, all by btf-package.js: decodeWeights for the 16-bit
  // files (wt-JJ.bin, versions 3 and 4's wt-JJ.z and wt-JJ.pz, version 4's wt-JJ-r.z over
  // the component's 8-bit weights), version 3's wt-JJ.webp checked (checkWeightsWebp),
  // decoded in the worker with its alpha and dequantised (dequantWeightsW): all marked
  // .precise; dequantWeights8 for versions 2 and 4's wt-JJ-8.png or version 4's
  // wt-JJ-8.webp (8-bit coarse, checked and decoded with its alpha as wt-JJ.webp is; the
  // codes kept for version 4's residuals), else null (only a texture).
  async weights(chunk, data) {
    const pkg = this.pkg, gpu = this.gpu;
    if (chunk.wt && pkg.manifestVersion === 3 && chunk.wt.endsWith('.webp')) {
      const img = await this.weightsImage(chunk, chunk.wt, data);
      const w = dequantWeightsW(pkg, chunk, img.width, img.height, img.rgba);
      w.precise = true;
      return w;
    }
    if (chunk.wt) {
      const w = await decodeWeights(pkg, chunk, data(chunk.wt), gpu.w8q.get(chunk.component));
      w.precise = true;
      return w;
    }
    if (!chunk.wt8) return null;
    let px;
    if (chunk.wt8.endsWith('.webp')) {
      const img = await this.weightsImage(chunk, chunk.wt8, data);
      px = weights8Webp(pkg, chunk, img.width, img.height, img.rgba);
    } else {
      const img = await this.image(chunk.wt8, data);
      const L = pkg.lights.dirs, V = pkg.views.dirs;
      if (img.width !== 3 * L || img.height !== V)
        throw new Error(`package ${pkg.name}: ${chunk.wt8} is ${img.width}x${img.height}, expected ${3 * L}x${V}`);
      px = gpu.readGrey(img);
    }
    gpu.w8q.set(chunk.component, px);
    return dequantWeights8(pkg, chunk, px);
  }

  // Uploads up to `max` queued chunks, in order; returns how many left the queue.
  upload(max) {
    let n = 0;
    for (let r; n < max && (r = this.ready.shift()); n++)
      if (r.j === this.gpu.uploaded) this.gpu.upload(r.j, r.img, r.wt);
    return n;
  }
}
