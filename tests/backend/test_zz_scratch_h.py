import time, httpx, sys
from backend.core.config import Settings
from tests.live_server import running_server
from tests.polling import free_udp_port

def test_probe(settings: Settings, experimenter) -> None:
    settings = settings.model_copy(update={
        "start_worker": True, "device_kind": "udp", "device_spawn_simulator": True,
        "device_address": f"127.0.0.1:{free_udp_port()}", "device_script": "standing"})
    t0 = time.time()
    with running_server(settings) as url:
        print("STARTED", time.time()-t0, file=sys.__stderr__)
        for i in range(80):
            r = httpx.get(url + "/api/health").json()
            print("H", round(time.time()-t0,1), r.get("worker",{}).get("ticks"), r.get("device",{}).get("alive"), r.get("device",{}).get("link_drops"), str(r.get("device",{}).get("identity"))[:80], file=sys.__stderr__)
            if i==0: print(r, file=sys.__stderr__)
            if r.get("device",{}).get("alive"): break
            time.sleep(0.5)
