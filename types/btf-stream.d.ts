// btf-stream/stream: the page-wide stream of a btfd (WebSocket, doc/protocol.md) or of a
// published library over HTTP, which <btf-viewer> and BTFMaterial use; a page may subscribe
// its own listeners. Hand-written for dist/btf-stream.js.

/** A listener's budget; -1 (or absent) means no limit. */
export interface BtfBudget {
  chunks?: number;
  bytes?: number;
  error?: number;
  /** device pixels one repeat of the material spans (the server's footprint rule) */
  pixels?: number;
  threshold?: number;
}

/** One material of a stream, shared by its listeners. */
export interface BtfSubscription {
  readonly stream: BtfStream;
  readonly material: string;
  /** The package's manifest.json (doc/package-format.md), once it arrived. */
  readonly manifest: Record<string, unknown> | null;
  /** chunk index -> its files' bytes, in the order of the manifest's "files" of that chunk */
  readonly chunks: Array<Uint8Array[] | undefined>;
  /** complete chunks held */
  readonly received: number;
  /** payload bytes received */
  readonly bytes: number;
  /** everything in the merged budget has arrived */
  readonly complete: boolean;
  readonly etag: string | null;
}

/** What a subscriber implements (every method optional but budget). */
export interface BtfListener {
  budget(): BtfBudget;
  onSubscribe?(sub: BtfSubscription): void;
  onManifest?(sub: BtfSubscription): void;
  onChunk?(sub: BtfSubscription, index: number): void;
  onComplete?(sub: BtfSubscription, msg: object): void;
  onError?(sub: BtfSubscription, msg: {code: string; message: string}): void;
  onStreamError?(sub: BtfSubscription, text: string, info: {retrying?: boolean; delayMs?: number; attempt?: number}): void;
  onStreamOpen?(sub: BtfSubscription): void;
}

export declare class BtfStream {
  /** The page's one stream of a source: ws(s):// (btfd) or http(s):// (a library folder). */
  static for(url: string): BtfStream;
  /** Every stream of the page. */
  static all(): BtfStream[];
  readonly url: string;
  /** Subscribes (or joins the subscription of) a material; chunks already held are replayed. */
  subscribe(material: string, listener: BtfListener): BtfSubscription;
  unsubscribe(sub: BtfSubscription, listener: BtfListener): void;
  /** Sends the subscription's merged budget when a listener's budget changed. */
  updateBudget(sub: BtfSubscription): void;
  /** Diagnostics: transport, bytes, subscriptions. */
  stats(): Record<string, unknown>;
}

/** The largest of several budgets (a limit only where every one has it). */
export declare function mergeBudgets(list: BtfBudget[]): Required<BtfBudget>;

/** The WebSocket subprotocol, btf-stream.v1. */
export declare const SUBPROTOCOL: string;
