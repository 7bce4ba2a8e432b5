// Never lose work: the scene being edited is kept in the browser (IndexedDB) a moment
// after every change, with its images inlined, and offered back on the next load.
//
// The storage is behind a small interface so the logic is tested without a browser; the
// page uses IndexedDB, where a scene with photographs (tens of megabytes) fits.

import { fileOf, PICTURE_KEYS, pictureName, pictureSlot, withPictureNamed } from './images';
import { serializeScene, type Pt, type SceneDoc } from './scene';
import type { Mode, Tool } from './state';


/** What is kept: the document, what it was called, and when and whether it was saved. */
export interface Snapshot {
  doc: SceneDoc;
  fileName: string;
  /** Milliseconds since the epoch when the snapshot was taken. */
  savedAt: number;
  /** Whether it holds changes that were not saved to a file. */
  unsaved: boolean;
  /** Where the editor was (rest or pose mode, the time), restored with the scene. */
  view?: KeptView;
  /**
   * The file a save writes to (the path `inkwarp edit SCENE` serves), or null when a save
   * downloads: restored work goes back to its file only when the page opened that file.
   */
  source?: string | null;
  /** The version of that file the work was read from or last saved as (see `Origin`). */
  version?: string | null;
  /**
   * The pictures of that file as the page that made the snapshot opened it ([`pictureMarks`]):
   * a restore takes a picture changed on disk since from the file (see `restorePictures`).
   */
  pictures?: Record<string, string>;
  /**
   * The file each of the work's pictures came from, where it came from one (its path as the
   * scene file names it; see `pictureFiles`): a restore that fails names it.
   */
  files?: Record<string, string>;
}

/** The part of the editor's view a snapshot keeps. */
export interface KeptView {
  mode: Mode;
  time: number;
  /** A feature being drawn (its points clicked, not yet finished) and its tool. */
  tool?: Tool;
  draft?: Pt[];
}

/**
 * A place that holds this tab's snapshot (`get`, `put`, `clear`), beside those other tabs
 * left: each tab keeps its own, so two tabs' unsaved work never overwrite each other.
 */
export interface SnapshotStore {
  get(): Promise<Snapshot | null>;
  put(s: Snapshot): Promise<void>;
  clear(): Promise<void>;
  /** Snapshots that tabs no longer open left, newest first. */
  left(): Promise<{ key: string; snapshot: Snapshot }[]>;
  /** Forgets another tab's snapshot (restored here, or declined). */
  drop(key: string): Promise<void>;
  /**
   * Keeps `s` under a key of its own that no tab holds (returned): never written over by a
   * tab, and offered on a later load as a closed tab's work is (see `left`).
   */
  setAside(s: Snapshot): Promise<string>;
}

/** A key for a snapshot set aside from `key`'s (see `SnapshotStore.setAside`). */
const asideKey = (key: string) => `${key}-aside-${Date.now().toString(36)}-${Math.random().toString(36).slice(2, 6)}`;

/** Which of `keys` belong to tabs still open (see `holdTab`); all where the browser cannot tell. */
export type OpenTabs = (keys: string[]) => Promise<Set<string>>;

/** Of `all` (key, snapshot) pairs, those other than `own` whose tab is closed, newest first. */
async function leftBehind(all: [string, Snapshot][], own: string, open: OpenTabs): Promise<{ key: string; snapshot: Snapshot }[]> {
  const others = all.filter(([k]) => k !== own);
  const live = await open(others.map(([k]) => k));
  return others.filter(([k]) => !live.has(k)).map(([key, snapshot]) => ({ key, snapshot })).sort((a, b) => b.snapshot.savedAt - a.snapshot.savedAt);
}

const noneOpen: OpenTabs = async () => new Set();

/** A snapshot store in memory (tests, and browsers without IndexedDB); `shared` plays IndexedDB. */
export class MemoryStore implements SnapshotStore {
  constructor(
    readonly key = 'tab',
    readonly shared = new Map<string, Snapshot>(),
    private open: OpenTabs = noneOpen,
  ) {}
  get value(): Snapshot | null {
    return this.shared.get(this.key) ?? null;
  }
  async get(): Promise<Snapshot | null> {
    return this.value;
  }
  async put(s: Snapshot): Promise<void> {
    this.shared.set(this.key, s);
  }
  async clear(): Promise<void> {
    this.shared.delete(this.key);
  }
  left(): Promise<{ key: string; snapshot: Snapshot }[]> {
    return leftBehind([...this.shared], this.key, this.open);
  }
  async drop(key: string): Promise<void> {
    this.shared.delete(key);
  }
  async setAside(s: Snapshot): Promise<string> {
    const key = asideKey(this.key);
    this.shared.set(key, s);
    return key;
  }
}

const DB = 'inkwarp-editor';
const STORE = 'autosave';
const LOCK = 'inkwarp-tab-';

/**
 * Takes the Web Lock of `key`: the function that lets it go, or null when another tab holds
 * it. Where the browser has no Web Locks (an address that is neither https nor this
 * machine), every key counts as held elsewhere (see `openTabs`).
 */
export function claimTab(key: string): Promise<(() => void) | null> {
  const locks = navigator.locks;
  if (!locks) return Promise.resolve(null);
  return new Promise((resolve) => {
    void locks.request(LOCK + key, { ifAvailable: true }, (lock) =>
      lock ? new Promise<void>((release) => resolve(release)) : resolve(null));
  });
}

/**
 * This tab's key: kept in sessionStorage, so a reload (or a closed tab reopened) finds its
 * own snapshot, and held as a Web Lock for as long as the tab lives, so other tabs can tell
 * its snapshot is not left behind. A duplicated tab, which copies sessionStorage while the
 * first still holds the key, takes a key of its own.
 */
export async function holdTab(): Promise<string> {
  const fresh = () => `tab-${Date.now().toString(36)}-${Math.random().toString(36).slice(2, 8)}`;
  let key = sessionStorage.getItem('inkwarp-tab') ?? fresh();
  // Held for as long as the tab lives: its release is never called.
  if (navigator.locks && !(await claimTab(key))) {
    key = fresh();
    await claimTab(key);
  }
  sessionStorage.setItem('inkwarp-tab', key);
  return key;
}

/** Which tabs are open, from the Web Locks they hold (all of them, without Web Locks). */
export const openTabs: OpenTabs = async (keys) => {
  if (!navigator.locks) return new Set(keys);
  const held = new Set(((await navigator.locks.query()).held ?? []).map((l) => l.name));
  return new Set(keys.filter((k) => held.has(LOCK + k)));
};

/** The snapshot store of the page: a record per tab in an IndexedDB object store. */
export class IndexedDbStore implements SnapshotStore {
  private db: Promise<IDBDatabase>;

  constructor(
    readonly key: string,
    private open: OpenTabs = openTabs,
    factory: IDBFactory = indexedDB,
  ) {
    this.db = new Promise((resolve, reject) => {
      const req = factory.open(DB, 1);
      req.onupgradeneeded = () => req.result.createObjectStore(STORE);
      req.onsuccess = () => resolve(req.result);
      req.onerror = () => reject(req.error ?? new Error('IndexedDB could not be opened.'));
    });
  }

  private async run<T>(mode: IDBTransactionMode, fn: (s: IDBObjectStore) => IDBRequest<T>): Promise<T> {
    const db = await this.db;
    return new Promise((resolve, reject) => {
      const tx = db.transaction(STORE, mode);
      const req = fn(tx.objectStore(STORE));
      if (mode === 'readonly') {
        // A read answers when its request does, and is not committed by hand: in Chromium a
        // large value (a kept copy with its picture, stored apart in a profile on disk) read in
        // a transaction committed with `commit()` completed before its request had a result.
        req.onsuccess = () => resolve(req.result);
      } else {
        // Committed at once, not when the page next gets to run: a write started as the page
        // is left (its "Leave site?" question answered) is then kept, not dropped with it.
        tx.commit?.();
        tx.oncomplete = () => resolve(req.result);
      }
      tx.onerror = () => reject(tx.error ?? new Error('IndexedDB failed.'));
      tx.onabort = () => reject(tx.error ?? new Error('IndexedDB was aborted (is the disk full?).'));
    });
  }

  async get(): Promise<Snapshot | null> {
    return ((await this.run('readonly', (s) => s.get(this.key))) as Snapshot | undefined) ?? null;
  }
  async put(snap: Snapshot): Promise<void> {
    await this.run('readwrite', (s) => s.put(snap, this.key));
  }
  async clear(): Promise<void> {
    await this.run('readwrite', (s) => s.delete(this.key));
  }
  async left(): Promise<{ key: string; snapshot: Snapshot }[]> {
    // Keys and values from one transaction, so that they pair up whatever other tabs write.
    const db = await this.db;
    const all = await new Promise<[string, Snapshot][]>((resolve, reject) => {
      const out: [string, Snapshot][] = [];
      const tx = db.transaction(STORE, 'readonly');
      const req = tx.objectStore(STORE).openCursor();
      req.onsuccess = () => {
        const cursor = req.result;
        if (!cursor) return;
        out.push([String(cursor.key), cursor.value as Snapshot]);
        cursor.continue();
      };
      tx.oncomplete = () => resolve(out);
      tx.onerror = () => reject(tx.error ?? new Error('IndexedDB failed.'));
    });
    return leftBehind(all, this.key, this.open);
  }
  async drop(key: string): Promise<void> {
    await this.run('readwrite', (s) => s.delete(key));
  }
  async setAside(snap: Snapshot): Promise<string> {
    const key = asideKey(this.key);
    await this.run('readwrite', (s) => s.put(snap, key));
    return key;
  }
}

/** Reads an image reference that is not a data: URI (a file the server hands out). */
export type Inliner = (reference: string) => Promise<string>;

/** The document with every image reference a `data:` URI, so it restores without a server. */
export async function inlineImages(doc: SceneDoc, inline: Inliner): Promise<SceneDoc> {
  const layers = await Promise.all(
    doc.layers.map(async (l) => {
      const out = { ...l };
      for (const k of PICTURE_KEYS) {
        const ref = l[k];
        if (typeof ref === 'string' && !ref.startsWith('data:')) out[k] = await inline(ref);
      }
      return out;
    }),
  );
  return { ...doc, layers };
}

/** The scene as a file holds it, its keys in one order: two documents saved alike compare equal. */
function canonical(doc: SceneDoc): string {
  const sorted = (v: unknown): unknown => Array.isArray(v) ? v.map(sorted)
    : v && typeof v === 'object' ? Object.fromEntries(Object.entries(v).filter(([, x]) => x !== undefined).sort(([a], [b]) => (a < b ? -1 : a > b ? 1 : 0)).map(([k, x]) => [k, sorted(x)]))
    : v;
  return JSON.stringify(sorted(JSON.parse(serializeScene(doc))));
}

/**
 * Whether kept work holds nothing its file does not (`file`: the scene as the page opened it
 * from the file, pictures inlined as kept work has them): a save that reached the file as the
 * page was left, its answer never seen, left the work kept as unsaved.
 */
export function sameScene(kept: SceneDoc, file: SceneDoc): boolean {
  return canonical(kept) === canonical(file);
}

/** A short mark of each layer's pictures (by layer name and key), to tell one changed. */
export function pictureMarks(doc: SceneDoc): Record<string, string> {
  const marks: Record<string, string> = {};
  for (const l of doc.layers) {
    for (const k of PICTURE_KEYS) {
      const ref = l[k];
      if (typeof ref !== 'string') continue;
      let h = 0x811c9dc5; // FNV-1a over the reference (a data: URI holds the picture's bytes)
      for (let i = 0; i < ref.length; i++) h = Math.imul(h ^ ref.charCodeAt(i), 0x01000193);
      marks[pictureSlot(l.name, k)] = `${ref.length}:${(h >>> 0).toString(36)}`;
    }
  }
  return marks;
}

/** The file each of `doc`'s pictures came from, where it is known (`fileOf`), keyed as `pictureMarks` keys them. */
export function pictureFiles(doc: SceneDoc): Record<string, string> {
  const files: Record<string, string> = {};
  for (const l of doc.layers) {
    for (const k of PICTURE_KEYS) {
      const file = l[k] === undefined ? undefined : fileOf(l[k]);
      if (file) files[pictureSlot(l.name, k)] = file;
    }
  }
  return files;
}

/**
 * Kept work, restored into the page that opened its file: every picture the work did not
 * change but the file did (retouched on disk since) is taken from the file as it is now
 * (`now`, the scene as this page opened it), so a save keeps naming the file's picture
 * rather than writing the kept, older copy into the scene. Returns the scene and the
 * names of the layers whose pictures were taken, and their keys ("layer name\0image", as
 * `pictureMarks` names them).
 */
export function restorePictures(kept: SceneDoc, opened: Record<string, string> | undefined, now: SceneDoc, nowMarks = pictureMarks(now)): { doc: SceneDoc; taken: string[]; keys: string[] } {
  if (!opened) return { doc: kept, taken: [], keys: [] };
  const keptMarks = pictureMarks(kept);
  const taken = new Set<string>();
  const keys: string[] = [];
  const layers = kept.layers.map((l) => {
    const fresh = now.layers.find((n) => n.name === l.name);
    const out = { ...l };
    for (const k of PICTURE_KEYS) {
      const key = pictureSlot(l.name, k);
      const unchangedHere = keptMarks[key] !== undefined && keptMarks[key] === opened[key];
      const changedThere = nowMarks[key] !== undefined && nowMarks[key] !== opened[key];
      if (fresh && unchangedHere && changedThere) {
        out[k] = fresh[k];
        taken.add(l.name);
        keys.push(key);
      }
    }
    return out;
  });
  return taken.size ? { doc: { ...kept, layers }, taken: [...taken], keys } : { doc: kept, taken: [], keys: [] };
}

/** Fetches a URL into a data: URI. */
export async function fetchDataUri(url: string): Promise<string> {
  const resp = await fetch(url);
  if (!resp.ok) throw new Error(`HTTP ${resp.status} for ${url}`);
  const blob = await resp.blob();
  return new Promise((resolve, reject) => {
    const r = new FileReader();
    r.onload = () => resolve(r.result as string);
    r.onerror = () => reject(r.error);
    r.readAsDataURL(blob);
  });
}

/** "14:32": the time of day of a snapshot, in the user's clock. */
export function clockTime(ms: number): string {
  const d = new Date(ms);
  return `${String(d.getHours()).padStart(2, '0')}:${String(d.getMinutes()).padStart(2, '0')}`;
}

/**
 * The question the page asks on load when an unsaved snapshot is waiting; `instead`: the
 * path of another scene file the page opened, which the restored one would replace (the
 * kept one is named by its own file's path where it had one: two files called scene.json
 * are told apart).
 */
export function restoreQuestion(s: Snapshot, now = Date.now(), instead?: string): string {
  const day = new Date(s.savedAt).toDateString() === new Date(now).toDateString() ? '' : ` on ${new Date(s.savedAt).toDateString()}`;
  const other = instead ? ` (${s.source ?? s.fileName}) instead of ${instead}` : '';
  return `Restore the scene you were editing at ${clockTime(s.savedAt)}${day}${other}?`;
}

/**
 * What a restore of `s` that failed says: `why`, the problems one a line ("at PATH: ..."),
 * each picture named by its file (else its layer) rather than by the data: URI the work
 * keeps it as (which the user never saw), then `where` the work is kept now and what to do.
 */
export function unopenedMessage(s: Snapshot, why: string, where: string): string {
  const files: (string | undefined)[] = [];
  const named = why.split('\n').map((line) => {
    const at = /^at (\S+): /.exec(line);
    return at ? withPictureNamed(s.doc, at[1], line, (layer, key) => {
      const file = s.files?.[pictureSlot(layer.name, key)];
      files.push(file);
      return `${pictureName(layer.name, key, file)} kept with it`;
    }) : line;
  });
  const paths = [...new Set(files)].map((f) => JSON.stringify(f)).join(', ');
  const mend = !files.length ? 'download it to mend that value in a text editor, then open the file'
    : s.source && files.every(Boolean) ? `download it, move it into the folder of ${s.source} and, in a text editor, replace ${files.length === 1 ? "that picture's data: URI by the path of its file" : "those pictures' data: URIs by the paths of their files"} (${paths}), then open it with \`inkwarp edit SCENE\``
    : `download it and, in a text editor, replace that picture's data: URI by the path of its file (from where you save the scene${s.source ? `, as ${s.source} names it` : ''}), then open it with \`inkwarp edit SCENE\``;
  return `The work kept from ${clockTime(s.savedAt)} could not be opened: ${named.join('\n').replace(/[.\s]+$/, '')}. ${where}; ${mend}.`;
}

/** How long after the last of a burst of edits the kept copy is written (ms). */
export const KEEP_DELAY_MS = 150;

/**
 * Keeps the snapshot up to date: `changed()` after each edit schedules a write `delayMs`
 * after the last of a burst of edits, and at most `maxWaitMs` after the first one not yet
 * written (a long drag is kept as it goes); `flush()` writes now. A picture is read and
 * inlined once: the writes after the first start at once, so a write asked for as the
 * page goes (`pagehide`) is begun before it has gone. Writes never overlap, and a failed
 * write is reported once through `onError`.
 */
export class Autosaver {
  private timer: ReturnType<typeof setTimeout> | null = null;
  /** When the first change not yet written was made (ms, `now`), or null. */
  private firstPending: number | null = null;
  private writing: Promise<void> = Promise.resolve();
  private reported = false;
  /** Pictures inlined before, by reference (a failed read is not kept). */
  private inlined = new Map<string, Promise<string>>();
  /** When the last snapshot was written (ms since the epoch), or null. */
  lastSavedAt: number | null = null;

  constructor(
    private store: SnapshotStore,
    private current: () => Omit<Snapshot, 'savedAt'>,
    private inline: Inliner,
    private delayMs = KEEP_DELAY_MS,
    private onError: (err: Error) => void = () => {},
    private now: () => number = Date.now,
    private maxWaitMs = 1000,
  ) {}

  /** The document changed: write it soon. */
  changed(): void {
    if (this.timer !== null) clearTimeout(this.timer);
    this.firstPending ??= this.now();
    const wait = Math.max(0, Math.min(this.delayMs, this.firstPending + this.maxWaitMs - this.now()));
    this.timer = setTimeout(() => {
      this.timer = null;
      void this.flush();
    }, wait);
  }

  /** Whether a write is scheduled but not yet started. */
  get pending(): boolean {
    return this.timer !== null;
  }

  /** Writes the current document now (after any write in progress). */
  flush(): Promise<void> {
    if (this.timer !== null) {
      clearTimeout(this.timer);
      this.timer = null;
    }
    this.firstPending = null;
    this.writing = this.writing.then(async () => {
      const { doc, ...rest } = this.current();
      // Pictures the document no longer names are forgotten.
      const named = new Set<unknown>(doc.layers.flatMap((l) => PICTURE_KEYS.map((k) => l[k])));
      for (const old of this.inlined.keys()) if (!named.has(old)) this.inlined.delete(old);
      try {
        const inlined = await inlineImages(doc, (ref) => this.inlineOnce(ref));
        const savedAt = this.now();
        await this.store.put({ ...rest, doc: inlined, savedAt });
        this.lastSavedAt = savedAt;
        this.reported = false;
      } catch (err) {
        if (!this.reported) this.onError(err as Error);
        this.reported = true;
      }
    });
    return this.writing;
  }

  /** `ref` inlined, read once. */
  private inlineOnce(ref: string): Promise<string> {
    let got = this.inlined.get(ref);
    if (!got) {
      got = this.inline(ref);
      this.inlined.set(ref, got);
      got.catch(() => this.inlined.delete(ref));
    }
    return got;
  }
}
