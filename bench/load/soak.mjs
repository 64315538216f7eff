// bench/load/soak.mjs - the churn of bench/bench_soak.sh against one btfd: AGENTS
// clients that, for MINUTES, keep connecting, subscribing to random materials with
// random budgets, changing budgets, unsubscribing, going away abruptly (TCP reset,
// no close frame) and stalling (they stop reading until btfd's --stall-timeout
// drops them). Prints one line per minute, `minute N actions A connects C resets R
// stalls S errors E` (E: error frames other than the ones a stall or a budget
// change may cause), and `soak_client_done` at the end.
//
//   node bench/load/soak.mjs PORT MINUTES AGENTS NAME...
import WebSocket from 'ws';

const [port, minutes, agents, ...names] = process.argv.slice(2);
const end = Date.now() + Number(minutes) * 60e3;
const counts = {actions: 0, connects: 0, resets: 0, stalls: 0, errors: 0};
let seed = 12345;
const rand = (n) => { // LCG: a run is repeatable
  seed = (seed * 1103515245 + 12345) >>> 0;
  return (seed >>> 8) % n;
};
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

function budget() {
  const k = rand(4);
  return k === 0 ? {chunks: 1 + rand(8)} : k === 1 ? {bytes: 20000 + rand(400000)} : k === 2 ? {error: 1 + rand(6)} : {};
}

// One connection's life: a few actions, then a clean close, a reset or a stall.
async function life() {
  const ws = new WebSocket(`ws://127.0.0.1:${port}/stream`, 'btf-stream.v1');
  counts.connects++;
  const subs = new Set();
  ws.on('message', (data, binary) => {
    if (binary) return;
    const m = JSON.parse(data.toString());
    if (m.type === 'error' && m.code !== 'not_subscribed' && m.code !== 'already_subscribed') counts.errors++;
  });
  ws.on('error', () => {});
  await new Promise((r) => { ws.once('open', r); ws.once('close', r); });
  if (ws.readyState !== WebSocket.OPEN) return;
  const steps = 1 + rand(6);
  for (let i = 0; i < steps && ws.readyState === WebSocket.OPEN && Date.now() < end; i++) {
    const name = names[rand(names.length)];
    const k = rand(4);
    if (k <= 1 || !subs.size) {
      ws.send(JSON.stringify({type: 'subscribe', material: name, budget: budget()}));
      subs.add(name);
    } else if (k === 2) {
      ws.send(JSON.stringify({type: 'budget', material: [...subs][0], budget: budget()}));
    } else {
      const s = [...subs][0];
      ws.send(JSON.stringify({type: 'unsubscribe', material: s}));
      subs.delete(s);
    }
    counts.actions++;
    await sleep(50 + rand(400));
  }
  const how = rand(10);
  if (how < 2) { // abrupt: a TCP reset, no close frame
    counts.resets++;
    ws._socket?.resetAndDestroy?.() ?? ws.terminate();
  } else if (how < 3) { // stall: stop reading until btfd drops the connection
    counts.stalls++;
    ws._socket?.pause();
    await new Promise((r) => { ws.once('close', r); setTimeout(r, 40e3); });
    ws.terminate();
  } else {
    ws.close();
  }
}

async function agent() {
  while (Date.now() < end) {
    await life().catch(() => {});
    await sleep(rand(200));
  }
}

let minute = 0;
const tick = setInterval(() => {
  minute++;
  console.log(`minute ${minute} actions ${counts.actions} connects ${counts.connects} resets ${counts.resets} ` +
    `stalls ${counts.stalls} errors ${counts.errors}`);
}, 60e3);
await Promise.all(Array.from({length: Number(agents)}, agent));
clearInterval(tick);
console.log('soak_client_done');
