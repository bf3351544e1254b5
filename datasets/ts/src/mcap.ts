// Opening a vtgen shard the way Foxglove does: @mcap/core's McapIndexedReader over random-access
// reads (summary, chunk indexes, then only the chunks asked for), zstd chunks decompressed by
// @foxglove/wasm-zstd (the decompressor Foxglove ships).
import { open, type FileHandle } from "node:fs/promises";

import { McapIndexedReader, type McapTypes } from "@mcap/core";
import zstd from "@foxglove/wasm-zstd";

/** @mcap/core's IReadable over a node file handle. */
export class FileHandleReadable implements McapTypes.IReadable {
  readonly #handle: FileHandle;
  readonly #size: bigint;

  constructor(handle: FileHandle, size: bigint) {
    this.#handle = handle;
    this.#size = size;
  }

  async size(): Promise<bigint> {
    return this.#size;
  }

  async read(offset: bigint, length: bigint): Promise<Uint8Array> {
    if (offset < 0n || length < 0n || offset + length > this.#size) {
      throw new Error(`read of ${length} bytes at ${offset} is outside the file (${this.#size} bytes)`);
    }
    const buffer = new Uint8Array(Number(length));
    let done = 0;
    while (done < buffer.length) {
      const { bytesRead } = await this.#handle.read(buffer, done, buffer.length - done, Number(offset) + done);
      if (bytesRead === 0) {
        throw new Error(`unexpected end of file at ${Number(offset) + done}`);
      }
      done += bytesRead;
    }
    return buffer;
  }
}

export type Shard = {
  path: string;
  reader: McapIndexedReader;
  close: () => Promise<void>;
};

let zstdReady: Promise<void> | undefined;

/** Opens one shard (a complete `*.mcap`) with McapIndexedReader; zstd is the only compression. */
export async function openShard(path: string): Promise<Shard> {
  zstdReady ??= zstd.isLoaded.then(() => undefined);
  await zstdReady;
  const handle = await open(path, "r");
  try {
    const size = BigInt((await handle.stat()).size);
    const reader = await McapIndexedReader.Initialize({
      readable: new FileHandleReadable(handle, size),
      decompressHandlers: {
        zstd: (data: Uint8Array, decompressedSize: bigint) => zstd.decompress(data, Number(decompressedSize)),
      },
    });
    return { path, reader, close: () => handle.close() };
  } catch (err) {
    await handle.close();
    throw err;
  }
}
