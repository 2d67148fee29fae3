"""A second MCAP implementation reads our logs: the TypeScript reader of the MCAP project
(@mcap/core, with @mcap/nodejs and @mcap/support for zstd), installed from npm into a cache
directory on first use.  It must agree on topics, schemas, encodings, message counts, times,
metadata and attachments, so our files are not only readable by our own code."""

from __future__ import annotations

import json
import os
import shutil
import subprocess

import pytest
from test_logs_fixtures import synthetic_arrays, write_arrays

from neck_sim.cache import cache_dir
from neck_sim.logs import neck_metadata, read_log
from neck_sim.params import default_params

NPM_PACKAGES = ("@mcap/core@2.2.2", "@mcap/nodejs@1.0.2", "@mcap/support@1.1.0")

READER_JS = r"""
import { McapIndexedReader } from "@mcap/core";
import { FileHandleReadable } from "@mcap/nodejs";
import { loadDecompressHandlers } from "@mcap/support";
import { open } from "fs/promises";

const fh = await open(process.argv[2], "r");
const reader = await McapIndexedReader.Initialize({
  readable: new FileHandleReadable(fh), decompressHandlers: await loadDecompressHandlers() });
const out = { library: reader.header.library, channels: {}, metadata: {}, attachments: {}, chunks: [] };
for (const ch of reader.channelsById.values()) {
  const schema = reader.schemasById.get(ch.schemaId);
  out.channels[ch.topic] = {
    messageEncoding: ch.messageEncoding, schemaName: schema.name, schemaEncoding: schema.encoding,
    schema: JSON.parse(new TextDecoder().decode(schema.data)),
    statisticsCount: Number(reader.statistics.channelMessageCounts.get(ch.id)),
    count: 0, timeMismatch: 0, first: null, last: null };
}
for (const c of reader.chunkIndexes) out.chunks.push(c.compression);
const byId = new Map([...reader.channelsById.values()].map((c) => [c.id, c.topic]));
for await (const msg of reader.readMessages()) {
  const ch = out.channels[byId.get(msg.channelId)];
  const body = JSON.parse(new TextDecoder().decode(msg.data));
  ch.count += 1;
  if (ch.first === null) ch.first = body;
  ch.last = body;
  if (msg.logTime !== msg.publishTime) ch.timeMismatch += 1;
  if ("t" in body && BigInt(Math.round(body.t * 1e9)) !== msg.logTime) ch.timeMismatch += 1;
}
for await (const m of reader.readMetadata()) out.metadata[m.name] = Object.fromEntries(m.metadata);
for await (const a of reader.readAttachments()) out.attachments[a.name] = new TextDecoder().decode(a.data);
await fh.close();
console.log(JSON.stringify(out));
"""


@pytest.fixture(scope="session")
def mcap_js():
    """Path of a node script reading an MCAP with @mcap/core (npm install on first use)."""
    node, npm = shutil.which("node"), shutil.which("npm")
    if node is None or npm is None:
        pytest.skip("node/npm not installed: the independent TypeScript MCAP reader cannot run")
    cache = cache_dir()
    prefix = os.path.join(cache, "npm-" + "-".join(p.replace("@", "").replace("/", "_") for p in NPM_PACKAGES))
    if not os.path.exists(os.path.join(prefix, "node_modules", "@mcap", "core", "package.json")):
        os.makedirs(prefix, exist_ok=True)
        proc = subprocess.run([npm, "install", "--prefix", prefix, "--no-audit", "--no-fund", "--loglevel=error",
                               *NPM_PACKAGES], capture_output=True, text=True, timeout=600)
        assert proc.returncode == 0, f"npm install {' '.join(NPM_PACKAGES)} failed:\n{proc.stderr}"
    script = os.path.join(prefix, "read_mcap.mjs")
    with open(script, "w") as fh:
        fh.write(READER_JS)
    return node, script


def read_with_js(mcap_js, path) -> dict:
    node, script = mcap_js
    proc = subprocess.run([node, script, str(path)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def test_typescript_reader_agrees(mcap_js, tmp_path):
    params = default_params(3)
    arrays = synthetic_arrays(params, seconds=0.6, seed=5)
    path = tmp_path / "run.mcap"
    write_arrays(path, params, arrays, mjcf_xml="<mujoco model='neck3x'/>", run_info={"seed": 11},
                 chunk_size=32 * 1024)
    js = read_with_js(mcap_js, path)

    contract = {"/neck/motors": ("motors", "neck_sim.Motors"), "/neck/camera": ("camera", "neck_sim.Camera"),
                "/neck/reference": ("reference", "neck_sim.Reference"),
                "/neck/estimate": ("estimate", "neck_sim.Estimate"), "/neck/truth": ("truth", "neck_sim.Truth")}
    assert set(js["channels"]) == set(contract) | {"/tf", "/neck/scene"}
    assert js["chunks"] and set(js["chunks"]) == {"zstd"}
    for topic, (name, schema_name) in contract.items():
        ch = js["channels"][topic]
        n_written = len(arrays[name]["t"])
        assert (ch["messageEncoding"], ch["schemaEncoding"], ch["schemaName"]) == ("json", "jsonschema", schema_name)
        assert ch["count"] == ch["statisticsCount"] == n_written, topic
        assert ch["timeMismatch"] == 0, topic
        assert set(ch["schema"]["required"]) == set(ch["first"]) == {"t", *(f for f in arrays[name] if f != "t")}
        for field, values in arrays[name].items():
            assert ch["first"][field] == values[0].tolist(), (topic, field)
            assert ch["last"][field] == values[-1].tolist(), (topic, field)
    tf, scene = js["channels"]["/tf"], js["channels"]["/neck/scene"]
    assert (tf["schemaName"], tf["schemaEncoding"], tf["messageEncoding"]) == ("foxglove.FrameTransforms",
                                                                             "jsonschema", "json")
    assert scene["schemaName"] == "foxglove.SceneUpdate"
    assert tf["count"] == tf["statisticsCount"] > 0 and tf["timeMismatch"] == 0
    assert {x["child_frame_id"] for x in tf["first"]["transforms"]} == {"neck", "bar0", "bar1", "bar2", "bar3"}
    assert js["metadata"]["neck"] == neck_metadata(params)
    assert js["metadata"]["run"]["seed"] == "11"
    assert js["attachments"] == {"neck.xml": "<mujoco model='neck3x'/>"}
    # and our reader agrees with it on the counts
    log = read_log(path)
    assert log.message_counts == {t: c["count"] for t, c in js["channels"].items()}
