// Just enough glTF 2.0 binary (GLB) to check a ModelPrimitive the way Foxglove will show it:
// header and chunks, the default scene's node transforms, and every mesh primitive's POSITION
// accessor (float32 VEC3). Foxglove loads glTF with three.js' GLTFLoader and then rotates the
// scene by +90° about x (glTF is y-up, Foxglove z-up), for every glTF model, whatever the panel
// settings; `foxgloveVertices` applies that rotation so the result is in the primitive's frame.

type Mat4 = number[]; // column-major, as glTF

type GltfNode = {
  children?: number[];
  mesh?: number;
  matrix?: number[];
  translation?: [number, number, number];
  rotation?: [number, number, number, number];
  scale?: [number, number, number];
};

type Gltf = {
  asset?: { version?: string };
  scene?: number;
  scenes?: { nodes?: number[] }[];
  nodes?: GltfNode[];
  meshes?: { primitives: { attributes: Record<string, number>; mode?: number }[] }[];
  accessors?: {
    bufferView?: number;
    byteOffset?: number;
    componentType: number;
    count: number;
    type: string;
    min?: number[];
    max?: number[];
  }[];
  bufferViews?: { buffer: number; byteOffset?: number; byteLength: number; byteStride?: number }[];
  buffers?: { byteLength: number; uri?: string }[];
};

export type Glb = { json: Gltf; bin: Uint8Array | undefined };

export function parseGlb(data: Uint8Array): Glb {
  const view = new DataView(data.buffer, data.byteOffset, data.byteLength);
  if (data.byteLength < 20 || view.getUint32(0, true) !== 0x46546c67) {
    throw new Error("not a GLB (magic 'glTF' missing)");
  }
  if (view.getUint32(4, true) !== 2) {
    throw new Error(`GLB version ${view.getUint32(4, true)}, expected 2`);
  }
  if (view.getUint32(8, true) !== data.byteLength) {
    throw new Error(`GLB header length ${view.getUint32(8, true)} != data length ${data.byteLength}`);
  }
  let offset = 12;
  let json: Gltf | undefined;
  let bin: Uint8Array | undefined;
  while (offset < data.byteLength) {
    const length = view.getUint32(offset, true);
    const type = view.getUint32(offset + 4, true);
    const body = data.subarray(offset + 8, offset + 8 + length);
    if (body.byteLength !== length) {
      throw new Error("GLB chunk runs past the end of the data");
    }
    if (length % 4 !== 0) {
      throw new Error("GLB chunk length is not a multiple of 4");
    }
    if (type === 0x4e4f534a) {
      json = JSON.parse(new TextDecoder().decode(body)) as Gltf;
    } else if (type === 0x004e4942) {
      bin = body;
    }
    offset += 8 + length;
  }
  if (json == undefined) {
    throw new Error("GLB has no JSON chunk");
  }
  if (json.asset?.version !== "2.0") {
    throw new Error(`glTF asset.version ${JSON.stringify(json.asset?.version)}, expected "2.0"`);
  }
  return { json, bin };
}

function identity(): Mat4 {
  return [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1];
}

function multiply(a: Mat4, b: Mat4): Mat4 {
  const out = new Array<number>(16).fill(0);
  for (let c = 0; c < 4; c++) {
    for (let r = 0; r < 4; r++) {
      let s = 0;
      for (let k = 0; k < 4; k++) {
        s += a[k * 4 + r]! * b[c * 4 + k]!;
      }
      out[c * 4 + r] = s;
    }
  }
  return out;
}

/** T * R * S of a pose (quaternion x, y, z, w), column-major. */
export function compose(t: [number, number, number], q: [number, number, number, number], s: [number, number, number]): Mat4 {
  const [x, y, z, w] = q;
  const r = [
    1 - 2 * (y * y + z * z), 2 * (x * y + z * w), 2 * (x * z - y * w),
    2 * (x * y - z * w), 1 - 2 * (x * x + z * z), 2 * (y * z + x * w),
    2 * (x * z + y * w), 2 * (y * z - x * w), 1 - 2 * (x * x + y * y),
  ];
  return [
    r[0]! * s[0], r[1]! * s[0], r[2]! * s[0], 0,
    r[3]! * s[1], r[4]! * s[1], r[5]! * s[1], 0,
    r[6]! * s[2], r[7]! * s[2], r[8]! * s[2], 0,
    t[0], t[1], t[2], 1,
  ];
}

function nodeMatrix(node: GltfNode): Mat4 {
  if (node.matrix != undefined) {
    return node.matrix;
  }
  return compose(node.translation ?? [0, 0, 0], node.rotation ?? [0, 0, 0, 1], node.scale ?? [1, 1, 1]);
}

/** Rotation by +90° about x: what Foxglove applies to every glTF scene (y-up to z-up). */
export const FOXGLOVE_GLTF_UP: Mat4 = compose([0, 0, 0], [Math.SQRT1_2, 0, 0, Math.SQRT1_2], [1, 1, 1]);

/**
 * All vertices of the default scene's meshes, transformed by their node chain, then by `outer`
 * (e.g. the primitive pose × scale × Foxglove's up-axis rotation). Returns a flat xyz array.
 */
export function sceneVertices(glb: Glb, outer: Mat4): Float64Array {
  const { json, bin } = glb;
  const sceneIndex = json.scene ?? 0;
  const scene = json.scenes?.[sceneIndex];
  if (scene == undefined) {
    throw new Error("glTF has no default scene");
  }
  const out: number[] = [];
  const visit = (index: number, parent: Mat4, depth: number): void => {
    if (depth > 64) {
      throw new Error("glTF node hierarchy is too deep (a cycle?)");
    }
    const node = json.nodes?.[index];
    if (node == undefined) {
      throw new Error(`glTF node ${index} does not exist`);
    }
    const m = multiply(parent, nodeMatrix(node));
    if (node.mesh != undefined) {
      const mesh = json.meshes?.[node.mesh];
      if (mesh == undefined) {
        throw new Error(`glTF mesh ${node.mesh} does not exist`);
      }
      for (const primitive of mesh.primitives) {
        const accessorIndex = primitive.attributes.POSITION;
        if (accessorIndex == undefined) {
          throw new Error("glTF primitive without POSITION");
        }
        const positions = readVec3Float(json, bin, accessorIndex);
        for (let i = 0; i < positions.length; i += 3) {
          const x = positions[i]!;
          const y = positions[i + 1]!;
          const z = positions[i + 2]!;
          out.push(
            m[0]! * x + m[4]! * y + m[8]! * z + m[12]!,
            m[1]! * x + m[5]! * y + m[9]! * z + m[13]!,
            m[2]! * x + m[6]! * y + m[10]! * z + m[14]!,
          );
        }
      }
    }
    for (const child of node.children ?? []) {
      visit(child, m, depth + 1);
    }
  };
  for (const root of scene.nodes ?? []) {
    visit(root, outer, 0);
  }
  return Float64Array.from(out);
}

function readVec3Float(json: Gltf, bin: Uint8Array | undefined, index: number): Float32Array {
  const accessor = json.accessors?.[index];
  if (accessor == undefined) {
    throw new Error(`glTF accessor ${index} does not exist`);
  }
  if (accessor.componentType !== 5126 || accessor.type !== "VEC3") {
    throw new Error(`POSITION accessor ${index} is not float32 VEC3`);
  }
  if (accessor.min == undefined || accessor.max == undefined) {
    throw new Error(`POSITION accessor ${index} lacks min/max (required by glTF 2.0)`);
  }
  const viewIndex = accessor.bufferView;
  const bufferView = viewIndex == undefined ? undefined : json.bufferViews?.[viewIndex];
  if (bufferView == undefined || bin == undefined) {
    throw new Error(`POSITION accessor ${index} has no data in the GLB's BIN chunk`);
  }
  if (bufferView.buffer !== 0 || json.buffers?.[0]?.uri != undefined) {
    throw new Error("a GLB ModelPrimitive must keep its data in the embedded buffer 0");
  }
  const stride = bufferView.byteStride ?? 12;
  const start = (bufferView.byteOffset ?? 0) + (accessor.byteOffset ?? 0);
  const end = start + stride * (accessor.count - 1) + 12;
  if (end > (bufferView.byteOffset ?? 0) + bufferView.byteLength || end > bin.byteLength) {
    throw new Error(`POSITION accessor ${index} runs past its buffer view`);
  }
  const view = new DataView(bin.buffer, bin.byteOffset, bin.byteLength);
  const out = new Float32Array(accessor.count * 3);
  for (let i = 0; i < accessor.count; i++) {
    for (let k = 0; k < 3; k++) {
      const v = view.getFloat32(start + i * stride + k * 4, true);
      out[i * 3 + k] = v;
      if (v < accessor.min[k]! - 1e-6 || v > accessor.max[k]! + 1e-6) {
        throw new Error(`POSITION accessor ${index}: value outside its declared min/max`);
      }
    }
  }
  return out;
}

export function multiplyMat(a: Mat4, b: Mat4): Mat4 {
  return multiply(a, b);
}

export function bounds(xyz: Float64Array): { min: number[]; max: number[] } {
  const min = [Infinity, Infinity, Infinity];
  const max = [-Infinity, -Infinity, -Infinity];
  for (let i = 0; i < xyz.length; i += 3) {
    for (let k = 0; k < 3; k++) {
      const v = xyz[i + k]!;
      if (v < min[k]!) min[k] = v;
      if (v > max[k]!) max[k] = v;
    }
  }
  return { min, max };
}

export { identity };
