// three.js as a glTF client (issue 23): load a .glb with GLTFLoader, play each clip with an
// AnimationMixer at the given frames, and write the CPU-skinned vertex positions
// (SkinnedMesh.getVertexPosition) as float32 (clips × frames × V × 3) to the output file.
// Usage: node gltf_three.mjs IN.glb OUT.bin FPS FRAME [FRAME ...]
import fs from "node:fs";
import * as THREE from "three";
import { GLTFLoader } from "three/addons/loaders/GLTFLoader.js";

const [input, output, fps, ...frames] = process.argv.slice(2);
const bytes = fs.readFileSync(input);
const data = bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength);
const gltf = await new Promise((resolve, reject) => new GLTFLoader().parse(data, "", resolve, reject));
let mesh = null;
gltf.scene.traverse((node) => { if (node.isSkinnedMesh && mesh === null) mesh = node; });
if (mesh === null) throw new Error("no skinned mesh");
const count = mesh.geometry.attributes.position.count;
const out = new Float32Array(gltf.animations.length * frames.length * count * 3);
const vertex = new THREE.Vector3();
let at = 0;
for (const clip of gltf.animations) {
  const mixer = new THREE.AnimationMixer(gltf.scene);
  const action = mixer.clipAction(clip);
  action.setLoop(THREE.LoopOnce, 1);
  action.clampWhenFinished = true;
  action.play();
  for (const frame of frames) {
    mixer.setTime(Number(frame) / Number(fps));
    gltf.scene.updateMatrixWorld(true);
    for (let i = 0; i < count; i++) {
      mesh.getVertexPosition(i, vertex);
      vertex.applyMatrix4(mesh.matrixWorld);
      out[at++] = vertex.x; out[at++] = vertex.y; out[at++] = vertex.z;
    }
  }
  mixer.stopAllAction();
  mixer.uncacheRoot(gltf.scene);
}
fs.writeFileSync(output, Buffer.from(out.buffer));
console.log(JSON.stringify({ clips: gltf.animations.map((c) => c.name), vertices: count }));
