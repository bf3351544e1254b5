// One shard read completely: channels parsed as Foxglove parses them, every message decoded and
// grouped by log time and by chunk. A snapshot shard's chunk is one sample (one log time); an
// episode shard's chunk (FORMAT.md, "Episodes") is one camera frame: the frame's messages at the
// chunk's first log time, then the touch and state messages up to the next frame.
import type { McapTypes } from "@mcap/core";

import { EPISODE_METADATA_KEY, SHARD_METADATA } from "./format.js";
import { parseChannel, type ParsedChannel } from "./foxglove.js";
import { openShard } from "./mcap.js";

export type Decoded = {
  topic: string;
  channelId: number;
  logTime: bigint;
  publishTime: bigint;
  sequence: number;
  value: Record<string, unknown>;
};

export type ChannelInfo = {
  channel: McapTypes.Channel;
  schema: McapTypes.Schema | undefined;
  parsed: ParsedChannel | undefined;
  error: Error | undefined;
};

export type ShardData = {
  path: string;
  header: McapTypes.Header;
  statistics: McapTypes.Statistics | undefined;
  chunkIndexes: readonly McapTypes.ChunkIndex[];
  metadata: Map<string, Map<string, string>>;
  channels: Map<number, ChannelInfo>;
  topics: Map<string, ChannelInfo>;
  messages: Decoded[];
  decodeErrors: string[];
  /** log time -> topic -> messages, in log-time order (every log time, an episode's touch and
   * state instants included) */
  samples: Map<bigint, Map<string, Decoded[]>>;
  /** The `vtgen.shard` `episode` record (parsed JSON) of an episode shard; undefined otherwise. */
  episode: Record<string, unknown> | undefined;
  /** The shard's samples in chunk order: each chunk's first log time -> topic -> its messages at
   * that time (a snapshot's sample; an episode's camera frame). */
  frames: Map<bigint, Map<string, Decoded[]>>;
  /** Each chunk's first log time -> its messages after that time, in log-time order (an
   * episode frame's touch and state streams up to the next frame; empty for a snapshot). */
  later: Map<bigint, Decoded[]>;
};

/** The first log times of the chunks holding messages, ascending: one per sample (frame). */
export function chunkStarts(chunkIndexes: readonly McapTypes.ChunkIndex[]): bigint[] {
  return chunkIndexes
    .filter((c) => c.messageIndexOffsets.size > 0)
    .map((c) => c.messageStartTime)
    .sort((a, b) => (a < b ? -1 : a > b ? 1 : 0));
}

/** The frame (chunk start time) whose chunk holds log time `t`: the latest start at or before it. */
export function frameTimeOf(starts: readonly bigint[], t: bigint): bigint | undefined {
  let lo = 0;
  let hi = starts.length;
  while (lo < hi) {
    const mid = (lo + hi) >> 1;
    if (starts[mid]! <= t) {
      lo = mid + 1;
    } else {
      hi = mid;
    }
  }
  return lo === 0 ? undefined : starts[lo - 1];
}

export async function readShard(path: string): Promise<ShardData> {
  const shard = await openShard(path);
  try {
    const { reader } = shard;
    const channels = new Map<number, ChannelInfo>();
    const topics = new Map<string, ChannelInfo>();
    for (const [id, channel] of reader.channelsById) {
      const schema = channel.schemaId === 0 ? undefined : reader.schemasById.get(channel.schemaId);
      let parsed: ParsedChannel | undefined;
      let error: Error | undefined;
      try {
        parsed = parseChannel(channel, schema);
      } catch (err) {
        error = err instanceof Error ? err : new Error(String(err));
      }
      const info = { channel, schema, parsed, error };
      channels.set(id, info);
      if (topics.has(channel.topic)) {
        throw new Error(`${path}: two channels on topic ${channel.topic}`);
      }
      topics.set(channel.topic, info);
    }

    const metadata = new Map<string, Map<string, string>>();
    for await (const record of reader.readMetadata()) {
      metadata.set(record.name, new Map(record.metadata));
    }

    const messages: Decoded[] = [];
    const decodeErrors: string[] = [];
    const samples = new Map<bigint, Map<string, Decoded[]>>();
    for await (const message of reader.readMessages({ validateCrcs: true })) {
      const info = channels.get(message.channelId);
      if (info == undefined) {
        decodeErrors.push(`message on unknown channel ${message.channelId}`);
        continue;
      }
      if (info.parsed == undefined) {
        continue; // the channel's own error is reported once
      }
      let value: Record<string, unknown>;
      try {
        value = info.parsed.deserialize(message.data);
      } catch (err) {
        decodeErrors.push(`${info.channel.topic} @ ${message.logTime}: ${String(err)}`);
        continue;
      }
      const decoded: Decoded = {
        topic: info.channel.topic,
        channelId: message.channelId,
        logTime: message.logTime,
        publishTime: message.publishTime,
        sequence: message.sequence,
        value,
      };
      messages.push(decoded);
      let sample = samples.get(message.logTime);
      if (sample == undefined) {
        sample = new Map();
        samples.set(message.logTime, sample);
      }
      const list = sample.get(decoded.topic) ?? [];
      list.push(decoded);
      sample.set(decoded.topic, list);
    }
    let episode: Record<string, unknown> | undefined;
    const record = metadata.get(SHARD_METADATA)?.get(EPISODE_METADATA_KEY);
    if (record != undefined) {
      const parsed: unknown = JSON.parse(record);
      if (typeof parsed !== "object" || parsed == null || Array.isArray(parsed)) {
        throw new Error(`${path}: vtgen.shard ${EPISODE_METADATA_KEY} is not a JSON object`);
      }
      episode = parsed as Record<string, unknown>;
    }
    // Chunks by their first log time: a chunk holds the sample at that time and (an episode frame)
    // the streams after it up to the next chunk's (the chunk indexes' time ranges do not overlap:
    // checked by the tests).
    const starts = chunkStarts(reader.chunkIndexes);
    const frames = new Map<bigint, Map<string, Decoded[]>>();
    const later = new Map<bigint, Decoded[]>();
    for (const t of starts) {
      frames.set(t, samples.get(t) ?? new Map());
      later.set(t, []);
    }
    for (const m of messages) {
      const frame = frameTimeOf(starts, m.logTime);
      if (frame != undefined && m.logTime !== frame) {
        later.get(frame)!.push(m);
      }
    }
    return {
      path,
      header: reader.header,
      statistics: reader.statistics,
      chunkIndexes: reader.chunkIndexes,
      metadata,
      channels,
      topics,
      messages,
      decodeErrors,
      samples,
      episode,
      frames,
      later,
    };
  } finally {
    await shard.close();
  }
}
