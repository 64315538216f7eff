// btf-decode-worker.js - the decode worker of btf-decode.js when the page and the
// script share an origin (a worker from a file: no blob: URL for a strict CSP to refuse).
import {decoderBody} from './btf-decode.js';

decoderBody(self);
