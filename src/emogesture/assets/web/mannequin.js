// emogesture's mannequin in WebGL: parses an emogesture .glb (one skinned mesh, one skin, one animation of
// every joint's rotation and the root's translation sampled at every frame, and with a face track a second
// skinned mesh named "face" with 52 morph targets and their weights; see emogesture/export/gltf.py), blends
// the face's morph targets on the CPU, skins both in the vertex shader and draws them with a simple light.
// Mouse: drag to orbit, wheel to zoom.
// makeViewer(canvas, audio, status) -> {upload(glbArrayBuffer) -> clip}: the clip plays in step with `audio`
// (its currentTime) when it has a source, else on its own clock; a live client overwrites the clip's
// `rotations` and `rootTranslation` of frame 0 to show the newest pose (and `face.track`'s first 52 values,
// with `face.shown` true, to show the newest face). Used by the app's 3D view and the live page.

const GL_TYPES = {5121: Uint8Array, 5123: Uint16Array, 5125: Uint32Array, 5126: Float32Array};
const WIDTHS = {SCALAR: 1, VEC2: 2, VEC3: 3, VEC4: 4, MAT4: 16};

function parseGlb(buffer) {
  const view = new DataView(buffer);
  if (view.getUint32(0, true) !== 0x46546c67) throw new Error("not a binary glTF file");
  const jsonLength = view.getUint32(12, true);
  const json = JSON.parse(new TextDecoder().decode(new Uint8Array(buffer, 20, jsonLength)));
  const binStart = 20 + jsonLength + 8;
  const view_of = (viewIndex, Type, count, offset) => {
    const v = json.bufferViews[viewIndex];
    return new Type(buffer, binStart + (v.byteOffset || 0) + (offset || 0), count);
  };
  const read = (index) => {
    const a = json.accessors[index];
    const Type = GL_TYPES[a.componentType];
    if (a.sparse) {  // zeros with a few rows given (the face's morph targets)
      const width = WIDTHS[a.type], out = new Type(a.count * width);
      const rows = view_of(a.sparse.indices.bufferView, GL_TYPES[a.sparse.indices.componentType], a.sparse.count);
      const values = view_of(a.sparse.values.bufferView, Type, a.sparse.count * width);
      rows.forEach((row, i) => { for (let c = 0; c < width; c++) out[row * width + c] = values[i * width + c]; });
      return out;
    }
    return view_of(a.bufferView, Type, a.count * WIDTHS[a.type], a.byteOffset);
  };
  return {json, read};
}

// the face's mesh and weights when the file has them: its targets kept as the rows each one moves
function loadFace({json, read}, anim) {
  const mesh = json.meshes.findIndex((m) => m.name === "face");
  if (mesh < 0) return null;
  const prim = json.meshes[mesh].primitives[0];
  const node = json.nodes.findIndex((n) => n.mesh === mesh);
  const channel = anim.channels.find((c) => c.target.node === node && c.target.path === "weights");
  const targets = prim.targets.map((t) => {
    const d = read(t.POSITION), rows = [];
    for (let v = 0; v < d.length / 3; v++) if (d[3 * v] || d[3 * v + 1] || d[3 * v + 2]) rows.push(v);
    return {rows, d};
  });
  const base = read(prim.attributes.POSITION);
  return {base, positions: new Float32Array(base), normals: read(prim.attributes.NORMAL),
          colors: read(prim.attributes.COLOR_0), jointIndex: read(prim.attributes.JOINTS_0),
          weights: read(prim.attributes.WEIGHTS_0), indices: read(prim.indices), targets,
          names: json.meshes[mesh].extras.targetNames, track: channel ? read(anim.samplers[channel.sampler].output) : null,
          shown: Boolean(channel)};
}

// the face's positions at time t: its rest plus each morph target times its weight (linear between frames)
function morphFace(face, clip, t) {
  const n = face.targets.length, f = Math.min(Math.max(t * clip.fps, 0), clip.frames - 1);
  const i = Math.floor(f), j = Math.min(i + 1, clip.frames - 1), w = f - i;
  face.positions.set(face.base);
  face.targets.forEach(({rows, d}, k) => {
    const weight = face.track ? (1 - w) * face.track[n * i + k] + w * face.track[n * j + k] : 0;
    if (weight === 0) return;
    for (const v of rows) {
      face.positions[3 * v] += weight * d[3 * v];
      face.positions[3 * v + 1] += weight * d[3 * v + 1];
      face.positions[3 * v + 2] += weight * d[3 * v + 2];
    }
  });
  return face.positions;
}

function loadClip({json, read}) {
  const prim = json.meshes[0].primitives[0];
  const attr = prim.attributes;
  const skin = json.skins[0];
  const joints = skin.joints;
  const nodeToJoint = new Map(joints.map((node, k) => [node, k]));
  const parents = joints.map(() => -1);
  joints.forEach((node, k) => (json.nodes[node].children || []).forEach((c) => {
    if (nodeToJoint.has(c)) parents[nodeToJoint.get(c)] = k;
  }));
  const rest = joints.map((node) => json.nodes[node].translation || [0, 0, 0]);
  const anim = json.animations[0];
  const times = read(anim.samplers[0].input);
  const rotations = joints.map(() => null);
  let rootTranslation = null;
  for (const ch of anim.channels) {
    const out = read(anim.samplers[ch.sampler].output);
    const k = nodeToJoint.get(ch.target.node);
    if (ch.target.path === "rotation") rotations[k] = out;
    else if (ch.target.path === "translation" && k === 0) rootTranslation = out;
  }
  return {
    positions: read(attr.POSITION), normals: read(attr.NORMAL), jointIndex: read(attr.JOINTS_0),
    weights: read(attr.WEIGHTS_0), indices: read(prim.indices), inverseBind: read(skin.inverseBindMatrices),
    parents, rest, times, rotations, rootTranslation, frames: times.length,
    fps: times.length > 1 ? (times.length - 1) / times[times.length - 1] : 30, face: loadFace({json, read}, anim),
  };
}

// 4x4 matrices, column-major as WebGL wants them
function fromRotationTranslation(q, t) {
  const [x, y, z, w] = q;
  return [1 - 2 * (y * y + z * z), 2 * (x * y + z * w), 2 * (x * z - y * w), 0,
          2 * (x * y - z * w), 1 - 2 * (x * x + z * z), 2 * (y * z + x * w), 0,
          2 * (x * z + y * w), 2 * (y * z - x * w), 1 - 2 * (x * x + y * y), 0,
          t[0], t[1], t[2], 1];
}

function multiply(a, b) {
  const out = new Array(16);
  for (let c = 0; c < 4; c++) {
    for (let r = 0; r < 4; r++) {
      out[c * 4 + r] = a[r] * b[c * 4] + a[4 + r] * b[c * 4 + 1] + a[8 + r] * b[c * 4 + 2] + a[12 + r] * b[c * 4 + 3];
    }
  }
  return out;
}

function perspective(fovy, aspect, near, far) {
  const f = 1 / Math.tan(fovy / 2);
  return [f / aspect, 0, 0, 0, 0, f, 0, 0, 0, 0, (far + near) / (near - far), -1, 0, 0, 2 * far * near / (near - far), 0];
}

function lookAt(eye, target) {
  const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
  const norm = (v) => { const l = Math.hypot(...v) || 1; return v.map((x) => x / l); };
  const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  const z = norm(sub(eye, target)), x = norm(cross([0, 1, 0], z)), y = cross(z, x);
  return [x[0], y[0], z[0], 0, x[1], y[1], z[1], 0, x[2], y[2], z[2], 0, -dot(x, eye), -dot(y, eye), -dot(z, eye), 1];
}

// the local rotation of joint k at time t: normalised linear blend of the two frames around t
function rotationAt(clip, k, t) {
  const r = clip.rotations[k];
  if (!r) return [0, 0, 0, 1];
  const f = Math.min(Math.max(t * clip.fps, 0), clip.frames - 1);
  const i = Math.floor(f), j = Math.min(i + 1, clip.frames - 1), w = f - i;
  const q = [0, 1, 2, 3].map((c) => (1 - w) * r[4 * i + c] + w * r[4 * j + c]);
  const l = Math.hypot(...q) || 1;
  return q.map((c) => c / l);
}

function rootAt(clip, t) {
  const r = clip.rootTranslation;
  if (!r) return clip.rest[0];
  const f = Math.min(Math.max(t * clip.fps, 0), clip.frames - 1);
  const i = Math.floor(f), j = Math.min(i + 1, clip.frames - 1), w = f - i;
  return [0, 1, 2].map((c) => (1 - w) * r[3 * i + c] + w * r[3 * j + c]);
}

function jointMatrices(clip, t) {
  const world = [];
  const out = new Float32Array(16 * clip.parents.length);
  clip.parents.forEach((p, k) => {
    const local = fromRotationTranslation(rotationAt(clip, k, t), k === 0 ? rootAt(clip, t) : clip.rest[k]);
    world[k] = p < 0 ? local : multiply(world[p], local);
    out.set(multiply(world[k], Array.from(clip.inverseBind.subarray(16 * k, 16 * k + 16))), 16 * k);
  });
  return out;
}

const VERTEX = `
attribute vec3 position; attribute vec3 normal; attribute vec4 joint; attribute vec4 weight; attribute vec3 color;
uniform mat4 joints[JOINTS]; uniform mat4 projection; uniform mat4 view;
varying vec3 vNormal; varying vec3 vColor;
void main() {
  vColor = color;
  mat4 skin = weight.x * joints[int(joint.x)] + weight.y * joints[int(joint.y)]
            + weight.z * joints[int(joint.z)] + weight.w * joints[int(joint.w)];
  vNormal = mat3(skin) * normal;
  gl_Position = projection * view * skin * vec4(position, 1.0);
}`;
const FRAGMENT = `
precision mediump float; varying vec3 vNormal; varying vec3 vColor;
void main() {
  vec3 n = normalize(vNormal);
  if (!gl_FrontFacing) n = -n;  // the face's parts are open surfaces, seen from both sides
  float light = 0.35 + 0.65 * max(dot(n, normalize(vec3(0.4, 0.8, 0.9))), 0.0);
  gl_FragColor = vec4(vColor * light, 1.0);
}`;

function compile(gl, vertex, fragment) {
  const program = gl.createProgram();
  for (const [type, source] of [[gl.VERTEX_SHADER, vertex], [gl.FRAGMENT_SHADER, fragment]]) {
    const shader = gl.createShader(type);
    gl.shaderSource(shader, source);
    gl.compileShader(shader);
    if (!gl.getShaderParameter(shader, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(shader));
    gl.attachShader(program, shader);
  }
  gl.linkProgram(program);
  if (!gl.getProgramParameter(program, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(program));
  return program;
}

function makeViewer(canvas, audio, status) {
  const gl = canvas.getContext("webgl", {preserveDrawingBuffer: true, antialias: true});
  if (!gl) { status.textContent = "this browser has no WebGL: the video shows the same animation"; return null; }
  let clip = null, program = null, buffers = null, faceBuffers = null, yaw = 0, pitch = 0.1, distance = 2.1, startedAt = performance.now();
  canvas.addEventListener("mousemove", (e) => {
    if (e.buttons & 1) { yaw -= e.movementX * 0.01; pitch = Math.max(-1.2, Math.min(1.2, pitch + e.movementY * 0.01)); }
  });
  canvas.addEventListener("wheel", (e) => { distance = Math.max(0.8, Math.min(8, distance * Math.exp(e.deltaY * 0.001))); e.preventDefault(); });

  function upload(glb) {
    clip = loadClip(parseGlb(glb));
    program = compile(gl, VERTEX.replace("JOINTS", String(clip.parents.length)), FRAGMENT);
    const attribute = (name, data, size, usage) => {
      const buffer = gl.createBuffer();
      gl.bindBuffer(gl.ARRAY_BUFFER, buffer);
      gl.bufferData(gl.ARRAY_BUFFER, data, usage || gl.STATIC_DRAW);
      return {location: gl.getAttribLocation(program, name), buffer, size, type: gl.FLOAT};
    };
    const elements = (data) => {
      const index = gl.createBuffer();
      gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, index);
      gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, data, gl.STATIC_DRAW);
      return {index, count: data.length};
    };
    const wood = new Float32Array(clip.positions.length).map((_, i) => [0.78, 0.60, 0.42][i % 3]);
    // WebGL 1 has no integer attributes: the joint indices as floats
    buffers = {attributes: [attribute("position", clip.positions, 3), attribute("normal", clip.normals, 3),
                            attribute("joint", new Float32Array(clip.jointIndex), 4), attribute("weight", clip.weights, 4),
                            attribute("color", wood, 3)], ...elements(clip.indices)};
    const face = clip.face;
    faceBuffers = face && {attributes: [attribute("position", face.positions, 3, gl.DYNAMIC_DRAW),
                                        attribute("normal", face.normals, 3),
                                        attribute("joint", new Float32Array(face.jointIndex), 4),
                                        attribute("weight", face.weights, 4), attribute("color", face.colors, 3)],
                           ...elements(face.indices)};
    startedAt = performance.now();
    return clip;
  }

  function drawMesh(mesh) {
    for (const b of mesh.attributes) {
      gl.bindBuffer(gl.ARRAY_BUFFER, b.buffer);
      gl.enableVertexAttribArray(b.location);
      gl.vertexAttribPointer(b.location, b.size, b.type, false, 0, 0);
    }
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, mesh.index);
    gl.drawElements(gl.TRIANGLES, mesh.count, gl.UNSIGNED_SHORT, 0);
  }

  function time() {
    if (audio && audio.src && !isNaN(audio.duration)) return audio.currentTime;  // in step with the speech
    return ((performance.now() - startedAt) / 1000) % Math.max(clip.frames / clip.fps, 1e-3);
  }

  function draw() {
    requestAnimationFrame(draw);
    const w = canvas.clientWidth || canvas.width, h = canvas.clientHeight || canvas.height;
    if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
    gl.viewport(0, 0, canvas.width, canvas.height);
    gl.clearColor(0.93, 0.94, 0.96, 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    if (!clip) return;
    gl.enable(gl.DEPTH_TEST);
    gl.useProgram(program);
    const t = time();
    const root = rootAt(clip, t);
    const target = [root[0], root[1] + 0.25, root[2]];
    const eye = [target[0] + distance * Math.sin(yaw) * Math.cos(pitch), target[1] + distance * Math.sin(pitch),
                 target[2] + distance * Math.cos(yaw) * Math.cos(pitch)];
    gl.uniformMatrix4fv(gl.getUniformLocation(program, "projection"), false,
                        new Float32Array(perspective(0.7, canvas.width / canvas.height, 0.05, 50)));
    gl.uniformMatrix4fv(gl.getUniformLocation(program, "view"), false, new Float32Array(lookAt(eye, target)));
    gl.uniformMatrix4fv(gl.getUniformLocation(program, "joints"), false, jointMatrices(clip, t));
    drawMesh(buffers);
    if (faceBuffers && clip.face.shown) {
      gl.bindBuffer(gl.ARRAY_BUFFER, faceBuffers.attributes[0].buffer);
      gl.bufferSubData(gl.ARRAY_BUFFER, 0, morphFace(clip.face, clip, t));
      drawMesh(faceBuffers);
    }
    canvas.dataset.frame = String(Math.round(t * clip.fps));  // for the tests: the frame on screen
  }
  requestAnimationFrame(draw);
  return {upload};
}

