// node three_pose.mjs NODE_MODULES FILE.glb TIME...: plays FILE's animation with three.js (GLTFLoader,
// AnimationMixer) and prints, as JSON, every bone's world position at each TIME (seconds) and the clip's length;
// for a mesh with named morph targets (the face), its morphTargetInfluences by name at each TIME.
import fs from "fs";
import {pathToFileURL} from "url";

const [modules, file, ...times] = process.argv.slice(2);
const THREE = await import(pathToFileURL(`${modules}/three/build/three.module.js`).href);
const {GLTFLoader} = await import(pathToFileURL(`${modules}/three/examples/jsm/loaders/GLTFLoader.js`).href);
const data = fs.readFileSync(file);
const buffer = data.buffer.slice(data.byteOffset, data.byteOffset + data.byteLength);
new GLTFLoader().parse(buffer, "", (gltf) => {
  const mixer = new THREE.AnimationMixer(gltf.scene);
  const action = mixer.clipAction(gltf.animations[0]);
  action.setLoop(THREE.LoopOnce);  // the last frame at the clip's end, not the first again
  action.clampWhenFinished = true;
  action.play();
  const skinned = [];
  gltf.scene.traverse((o) => { if (o.isSkinnedMesh) skinned.push(o); });
  const bones = skinned[0].skeleton.bones;
  const morphed = skinned.filter((m) => m.morphTargetDictionary && Object.keys(m.morphTargetDictionary).length);
  const out = {duration: gltf.animations[0].duration, bones: bones.length, skinned: skinned.length, poses: {},
               morphs: {}, morph_mesh: morphed.length ? morphed[0].name : null};
  for (const t of times) {
    mixer.setTime(Number(t));
    gltf.scene.updateMatrixWorld(true);
    out.poses[t] = Object.fromEntries(bones.map((b) => [b.name, b.getWorldPosition(new THREE.Vector3()).toArray()]));
    if (morphed.length) {
      const m = morphed[0];
      out.morphs[t] = Object.fromEntries(Object.entries(m.morphTargetDictionary).map(
        ([name, i]) => [name, m.morphTargetInfluences[i]]));
    }
  }
  console.log(JSON.stringify(out));
}, (error) => { console.error(`three.js could not load ${file}: ${error}`); process.exit(2); });
