// three.js as an FBX client (issue 67): load a .fbx with FBXLoader, play its first clip with an
// AnimationMixer at the given frames, and write the CPU-skinned vertex positions of its skinned
// mesh (SkinnedMesh.getVertexPosition, in world space) as float32 (frames × V × 3) to the output.
// Usage: node fbx_three.mjs IN.fbx OUT.bin FPS FRAME [FRAME ...]
import fs from "node:fs";
import * as THREE from "three";
import { FBXLoader } from "three/addons/loaders/FBXLoader.js";

const [input, output, fps, ...frames] = process.argv.slice(2);
const bytes = fs.readFileSync(input);
const scene = new FBXLoader().parse(bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength), "");
let mesh = null;
scene.traverse((node) => { if (node.isSkinnedMesh && mesh === null) mesh = node; });
if (mesh === null) throw new Error("no skinned mesh");
if (scene.animations.length === 0) throw new Error("no animation");
const count = mesh.geometry.attributes.position.count;
const out = new Float32Array(frames.length * count * 3);
const vertex = new THREE.Vector3();
const mixer = new THREE.AnimationMixer(scene);
const action = mixer.clipAction(scene.animations[0]);
action.setLoop(THREE.LoopOnce, 1);
action.clampWhenFinished = true;
action.play();
let at = 0;
for (const frame of frames) {
  mixer.setTime(Number(frame) / Number(fps));
  scene.updateMatrixWorld(true);
  for (let i = 0; i < count; i++) {
    mesh.getVertexPosition(i, vertex);
    vertex.applyMatrix4(mesh.matrixWorld);
    out[at++] = vertex.x; out[at++] = vertex.y; out[at++] = vertex.z;
  }
}
fs.writeFileSync(output, Buffer.from(out.buffer));
const uv = mesh.geometry.attributes.uv;  // each corner's (u, v), beside the positions as OUT.uv
if (uv) fs.writeFileSync(output + ".uv", Buffer.from(new Float32Array(uv.array).buffer));
console.log(JSON.stringify({ clips: scene.animations.map((c) => c.name), vertices: count,
  duration: scene.animations[0].duration }));
