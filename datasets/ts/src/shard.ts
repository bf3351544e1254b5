// One shard read completely: channels parsed as Foxglove parses them, every message decoded and
// grouped by sample (log time).
import type { McapTypes } from "@mcap/core";

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
  /** log time -> topic -> messages, in log-time order */
  samples: Map<bigint, Map<string, Decoded[]>>;
};

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
    };
  } finally {
    await shard.close();
  }
}
