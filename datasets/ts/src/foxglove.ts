// How Foxglove turns an MCAP channel into a message decoder, restated for the encodings vtgen
// writes (see FORMAT.md, "MCAP shard"):
// - message encoding `protobuf` needs schema encoding `protobuf`; the schema data is a
//   FileDescriptorSet, loaded with protobufjs' `Root.fromDescriptor`, and the schema *name* must be
//   the fully-qualified message type in it (`foxglove.RawImage`). Foxglove recognises its own
//   schemas (what the 3D and Image panels render) by that name alone.
// - message encoding `json` needs schema encoding `jsonschema` (or no schema). Foxglove derives the
//   message's fields from the JSON Schema and accepts only `type: object` at the root and
//   properties of type boolean, string, number, integer, object, or array of those (or `oneOf` of
//   numeric constants); anything else (a missing type, "null", a list of types) makes the whole
//   channel undecodable in Foxglove, so the check below rejects it too.
import protobuf from "protobufjs";
import descriptor from "protobufjs/ext/descriptor/index.js";

import type { McapTypes } from "@mcap/core";

/** The Foxglove schemas the 3D and Image panels draw, by schema name. */
export const FOXGLOVE_RENDERABLE_SCHEMAS = new Set([
  "foxglove.CameraCalibration",
  "foxglove.CompressedImage",
  "foxglove.FrameTransform",
  "foxglove.FrameTransforms",
  "foxglove.Grid",
  "foxglove.LaserScan",
  "foxglove.PointCloud",
  "foxglove.PoseInFrame",
  "foxglove.PosesInFrame",
  "foxglove.RawImage",
  "foxglove.SceneUpdate",
]);

export const IMAGE_SCHEMAS = new Set(["foxglove.RawImage", "foxglove.CompressedImage"]);
export const CALIBRATION_SCHEMAS = new Set(["foxglove.CameraCalibration"]);

export type ParsedChannel =
  | { kind: "protobuf"; type: protobuf.Type; deserialize: (data: Uint8Array) => Record<string, unknown> }
  | { kind: "json"; fields: string[]; deserialize: (data: Uint8Array) => Record<string, unknown> };

type RootWithDescriptor = typeof protobuf.Root & { fromDescriptor(set: unknown): protobuf.Root };

/** Decoder for one channel, or an Error saying why Foxglove could not decode it. */
export function parseChannel(channel: McapTypes.Channel, schema: McapTypes.Schema | undefined): ParsedChannel {
  if (channel.messageEncoding === "protobuf") {
    if (schema?.encoding !== "protobuf") {
      throw new Error(
        `${channel.topic}: message encoding protobuf needs schema encoding protobuf, got ${schema?.encoding ?? "no schema"}`,
      );
    }
    return parseProtobufSchema(schema.name, schema.data);
  }
  if (channel.messageEncoding === "json") {
    if (schema != undefined && schema.encoding !== "jsonschema") {
      throw new Error(
        `${channel.topic}: message encoding json needs schema encoding jsonschema (or none), got ${schema.encoding}`,
      );
    }
    let fields: string[] = [];
    if (schema != undefined && schema.data.length > 0) {
      const parsed: unknown = JSON.parse(new TextDecoder().decode(schema.data));
      if (typeof parsed !== "object" || parsed == null || Array.isArray(parsed)) {
        throw new Error(`${channel.topic}: JSON schema is not an object`);
      }
      fields = checkJsonSchema(parsed as Record<string, unknown>, schema.name);
    }
    const decoder = new TextDecoder("utf-8", { fatal: true });
    return {
      kind: "json",
      fields,
      deserialize: (data) => {
        const value: unknown = JSON.parse(decoder.decode(data));
        if (typeof value !== "object" || value == null || Array.isArray(value)) {
          throw new Error(`${channel.topic}: JSON message is not an object`);
        }
        return value as Record<string, unknown>;
      },
    };
  }
  throw new Error(`${channel.topic}: message encoding ${channel.messageEncoding} is not one vtgen writes`);
}

export function parseProtobufSchema(name: string, data: Uint8Array): ParsedChannel {
  const set = descriptor.FileDescriptorSet.decode(data);
  const root = (protobuf.Root as RootWithDescriptor).fromDescriptor(set);
  root.resolveAll();
  // Foxglove looks the schema name up as given: it must be the fully-qualified type name.
  const found = root.lookup(name);
  if (!(found instanceof protobuf.Type) || found.fullName !== `.${name}`) {
    throw new Error(`schema name ${name} is not a fully-qualified message type of its FileDescriptorSet`);
  }
  const type = found;
  return {
    kind: "protobuf",
    type,
    // As Foxglove: every field present (defaults), int64 as decimal strings here (Foxglove: bigint).
    deserialize: (bytes) =>
      type.toObject(type.decode(bytes), { defaults: true, longs: String, arrays: true }) as Record<string, unknown>,
  };
}

/**
 * Checks a JSON Schema against the subset Foxglove turns into message fields and returns the
 * dotted field paths it yields; throws on the first construct Foxglove would reject.
 */
export function checkJsonSchema(schema: Record<string, unknown>, typeName: string, path: string[] = []): string[] {
  const where = path.length > 0 ? path.join(".") : typeName;
  if (schema.type !== "object") {
    throw new Error(`${where}: Foxglove needs "type": "object" here, got ${JSON.stringify(schema.type)}`);
  }
  const fields: string[] = [];
  const properties = (schema.properties ?? {}) as Record<string, Record<string, unknown>>;
  for (const [name, field] of Object.entries(properties)) {
    const fieldPath = [...path, name];
    const label = fieldPath.join(".");
    fields.push(label);
    if (Array.isArray(field.oneOf)) {
      if (!field.oneOf.every((alt: { const?: unknown }) => typeof alt.const === "number")) {
        throw new Error(`${label}: Foxglove accepts oneOf only with numeric const alternatives`);
      }
      continue;
    }
    switch (field.type) {
      case "boolean":
      case "number":
      case "integer":
        break;
      case "string":
        if (field.contentEncoding != undefined && field.contentEncoding !== "base64") {
          throw new Error(`${label}: contentEncoding ${JSON.stringify(field.contentEncoding)} is not supported`);
        }
        break;
      case "object":
        fields.push(...checkJsonSchema(field, typeName, fieldPath));
        break;
      case "array": {
        const items = field.items as Record<string, unknown> | undefined;
        if (items == undefined) {
          throw new Error(`${label}: an array needs "items" with a type`);
        }
        if (items.type === "object") {
          fields.push(...checkJsonSchema(items, typeName, fieldPath));
        } else if (!["boolean", "string", "number", "integer"].includes(String(items.type))) {
          throw new Error(`${label}: array items of type ${JSON.stringify(items.type)} are not supported`);
        } else if (items.type === "string" && items.contentEncoding != undefined) {
          throw new Error(`${label}: string array items cannot have a contentEncoding`);
        }
        break;
      }
      default:
        throw new Error(`${label}: type ${JSON.stringify(field.type)} is not supported by Foxglove`);
    }
  }
  return fields;
}

/** A protobuf enum's value by name, from the decoded schema (as Foxglove reads numbers). */
export function enumValue(type: protobuf.Type, enumName: string, valueName: string): number {
  const e = type.lookupEnum(enumName);
  const v = e.values[valueName];
  if (v == undefined) {
    throw new Error(`enum ${enumName} has no value ${valueName}`);
  }
  return v;
}

/** google.protobuf.Timestamp / Duration (decoded with longs as strings) to nanoseconds. */
export function toNanos(time: unknown): bigint {
  const t = time as { seconds?: string | number; nanos?: number } | null | undefined;
  if (t == undefined) {
    throw new Error("missing timestamp");
  }
  return BigInt(t.seconds ?? 0) * 1_000_000_000n + BigInt(t.nanos ?? 0);
}
