// Load one GLB with three.js's GLTFLoader, play its first animation with an AnimationMixer, and print on
// stdout, as JSON, what a three.js page would see: the meshes (morph influences, dictionary), the clips
// (duration, tracks) and, at each requested time, the morph influences, the quaternion of every named node
// and the world-space positions of the morphed vertices of the first morphed mesh (``positions``) and of every
// morphed mesh by name (``meshPositions``; skinned meshes skinned).
// Usage: [FP_CLIP=NAME] node three_load.mjs PREFIX FILE TIME...   (PREFIX holds node_modules/three; FP_CLIP
// plays the clip of that name instead of the first).
// Textures do not load in Node: the image loader fails at once, GLTFLoader reports it on stderr and goes on.
import fs from "node:fs";
import path from "node:path";
import { pathToFileURL } from "node:url";

const [prefix, file, ...timeArgs] = process.argv.slice(2);
const root = path.join(prefix, "node_modules", "three");
const load = (rel) => import(pathToFileURL(path.join(root, rel)).href);
// the same file that GLTFLoader's own `import ... from "three"` resolves to, so one copy of the library
const THREE = await load("build/three.module.js");
const { GLTFLoader } = await load("examples/jsm/loaders/GLTFLoader.js");
// Node has no image decoder: an embedded image fails to load (GLTFLoader reports it and goes on without it)
globalThis.self ??= globalThis;  // GLTFLoader reads self.URL for embedded images
THREE.TextureLoader.prototype.load = function (url, onLoad, onProgress, onError) {
    if (onError) onError(new Error("images do not load in Node"));
    return new THREE.Texture();
};

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
    out.meshPositions = {};
    for (const m of meshes.filter((x) => x.morphTargetInfluences)) {
        const list = [];
        for (let i = 0; i < m.geometry.attributes.position.count; i++) {
            m.getVertexPosition(i, vertex);
            vertex.applyMatrix4(m.matrixWorld);
            list.push(vertex.toArray());
        }
        out.meshPositions[m.name] = list;
    }
    return out;
}

const samples = [];
if (gltf.animations.length) {
    const mixer = new THREE.AnimationMixer(scene);
    const wanted = process.env.FP_CLIP;
    const clip = wanted ? gltf.animations.find((c) => c.name === wanted) : gltf.animations[0];
    if (!clip) throw new Error(`no animation named ${wanted}`);
    const action = mixer.clipAction(clip);
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
