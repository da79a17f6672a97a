// Load one GLB with three.js's GLTFLoader, play its first animation with an AnimationMixer, and print on
// stdout, as JSON, what a three.js page would see: the meshes (morph influences, dictionary), the clips
// (duration, tracks) and, at each requested time, the morph influences, the quaternion of every named node
// and the world-space positions of the morphed vertices of the first morphed mesh.
// Usage: node three_load.mjs PREFIX FILE TIME...   (PREFIX holds node_modules/three)
// No polyfills: the file has no textures, so no image loading; TextDecoder is Node's own.
import fs from "node:fs";
import path from "node:path";
import { pathToFileURL } from "node:url";

const [prefix, file, ...timeArgs] = process.argv.slice(2);
const root = path.join(prefix, "node_modules", "three");
const load = (rel) => import(pathToFileURL(path.join(root, rel)).href);
// the same file that GLTFLoader's own `import ... from "three"` resolves to, so one copy of the library
const THREE = await load("build/three.module.js");
const { GLTFLoader } = await load("examples/jsm/loaders/GLTFLoader.js");

const bytes = fs.readFileSync(file);
const buffer = bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength);
const gltf = await new Promise((resolve, reject) => {
    new GLTFLoader().parse(buffer, "", resolve, (err) => reject(err));
});
const scene = gltf.scene;

const meshes = [];
const named = [];
scene.traverse((o) => {
    if (o.isMesh) meshes.push(o);
    if (o.name) named.push(o);
});
const morphed = meshes.find((m) => m.morphTargetInfluences);

const clips = gltf.animations.map((clip) => ({
    name: clip.name,
    duration: clip.duration,
    tracks: clip.tracks.map((t) => ({
        name: t.name, type: t.ValueTypeName, keys: t.times.length, valueSize: t.getValueSize(),
    })),
}));

const vertex = new THREE.Vector3();
function snapshot(time) {
    scene.updateMatrixWorld(true);
    const out = { time, influences: morphed ? Array.from(morphed.morphTargetInfluences) : null, quaternions: {} };
    for (const o of named) out.quaternions[o.name] = o.quaternion.toArray();
    if (morphed) {
        const count = morphed.geometry.attributes.position.count;
        const positions = [];
        for (let i = 0; i < count; i++) {
            morphed.getVertexPosition(i, vertex);  // base + Σ influence × relative morph target
            vertex.applyMatrix4(morphed.matrixWorld);
            positions.push(vertex.toArray());
        }
        out.positions = positions;
    }
    return out;
}

const samples = [];
if (gltf.animations.length) {
    const mixer = new THREE.AnimationMixer(scene);
    const action = mixer.clipAction(gltf.animations[0]);
    action.setLoop(THREE.LoopOnce, 1);
    action.clampWhenFinished = true;
    action.play();
    let now = 0;
    for (const arg of timeArgs) {
        const time = Number(arg);
        if (!(time >= now)) throw new Error(`times must be ascending numbers, got ${arg}`);
        mixer.update(time - now);  // played forward as a page's render loop would, not jumped to
        now = time;
        samples.push(snapshot(time));
    }
}

process.stdout.write(JSON.stringify({
    revision: THREE.REVISION,
    meshes: meshes.map((m) => ({
        name: m.name,
        influences: m.morphTargetInfluences ? m.morphTargetInfluences.length : 0,
        dictionary: m.morphTargetDictionary ?? null,
        relative: m.geometry.morphTargetsRelative,
    })),
    clips,
    samples,
}));
