#!/usr/bin/env bash
# End to end in a real browser: `spangle render --watch --serve 0` on a temporary copy of a
# scene, the page opened in headless Chromium (driven over WebDriver by chromedriver, with curl).
# Checks that the page shows the latest pass (its image, its spp, the reload log), then changes a
# material's colour from red to blue and checks that the same open page updates by itself: the
# reload line arrives in the page's log, and the screenshot's image area turns from red to blue.
# Also: fixed routes only (404 elsewhere), requests for a foreign Host refused.
#   serve_page.sh SPANGLE PLUGIN_DIR REPO_DIR
set -u
S=$1 PLUGINS=$2 REPO=$3
command -v chromium > /dev/null && command -v chromedriver > /dev/null && command -v curl > /dev/null ||
    { echo "SKIP: chromium, chromedriver or curl missing (bash scripts/install-deps.sh --tests)"; exit 77; }
T=$(mktemp -d)
PID= DRIVER=
trap '[ -n "$PID" ] && kill -9 $PID 2>/dev/null; [ -n "$DRIVER" ] && kill $DRIVER 2>/dev/null; rm -rf "$T"' EXIT
cd "$T"
sed -e "s|\.\./\.\./assets/|$REPO/assets/|" "$REPO/tests/scenes/small_lit.toml" > scene.toml

fail() { echo "FAIL: $*"; echo "--- spangle"; cat log.txt; echo "--- chromedriver"; tail -20 driver.txt; exit 1; }
wait_for() {  # wait_for CMD... : retries for up to 30 s
    for _ in $(seq 1 300); do "$@" > /dev/null 2>&1 && return 0; sleep 0.1; done
    return 1
}

"$S" render scene.toml -o out.exr --watch --size 320x192 --spp 16 --serve 0 \
    --plugin-path "$PLUGINS" > log.txt 2>&1 &
PID=$!
wait_for grep -q "^live preview at http" log.txt || fail "no address printed"
URL=$(grep -o "http://127.0.0.1:[0-9]*/" log.txt | head -1)
wait_for grep -q "watching for changes" log.txt || fail "first render did not finish"

# The server: fixed routes only, loopback Host only.
[ "$(curl -s -o /dev/null -w '%{http_code}' "${URL}image.png")" = 200 ] || fail "no image"
[ "$(curl -s -o /dev/null -w '%{http_code}' "${URL}scene.toml")" = 404 ] || fail "serves other paths"
[ "$(curl -s -o /dev/null -w '%{http_code}' --path-as-is "${URL}../../etc/passwd")" != 200 ] ||
    fail "serves files"
[ "$(curl -s -o /dev/null -w '%{http_code}' -H 'Host: example.com' "$URL")" = 403 ] ||
    fail "answers a foreign Host"

# The browser, over WebDriver.
for try in 1 2 3 4 5; do
    DPORT=$((20000 + RANDOM % 20000))
    chromedriver --port=$DPORT > driver.txt 2>&1 &
    DRIVER=$!
    wait_for curl -sf "http://127.0.0.1:$DPORT/status" && break
    kill $DRIVER 2>/dev/null; DRIVER=
done
[ -n "$DRIVER" ] || fail "chromedriver did not start"
WD="http://127.0.0.1:$DPORT"
CAPS='{"capabilities":{"alwaysMatch":{"browserName":"chrome","goog:chromeOptions":{"binary":"/usr/bin/chromium","args":["--headless=new","--no-sandbox","--disable-gpu","--disable-dev-shm-usage","--hide-scrollbars","--window-size=800,600"]}}}}'
SID=$(curl -s -X POST -H 'Content-Type: application/json' -d "$CAPS" "$WD/session" |
    grep -o '"sessionId":"[^"]*"' | cut -d'"' -f4)
[ -n "$SID" ] || fail "no browser session"
curl -s -X POST -H 'Content-Type: application/json' -d "{\"url\":\"$URL\"}" "$WD/session/$SID/url" > /dev/null
page() {  # page JS-EXPRESSION: its value, as WebDriver returns it
    curl -s -X POST -H 'Content-Type: application/json' \
        -d "{\"script\":\"return String($1);\",\"args\":[]}" "$WD/session/$SID/execute/sync"
}
shot() {  # shot FILE: a screenshot of the page
    curl -s "$WD/session/$SID/screenshot" | sed -e 's/.*"value":"//' -e 's/".*//' | base64 -d > "$1"
}
shown() {  # the page's image has loaded and its status names the finished pass
    page "document.getElementById('image').complete && document.getElementById('image').naturalWidth" |
        grep -q '"value":"320"' &&
        page "document.getElementById('status').textContent" | grep -q "16 of 16 spp"
}
wait_for shown || fail "the page does not show the finished image: $(page "document.body.innerText")"
page "document.getElementById('log').textContent" | grep -q "loaded scene.toml" ||
    fail "the page's log lacks the load line"
shot before.png

sed -i 's/albedo = \[0.8, 0.1, 0.1\]/albedo = [0.1, 0.1, 0.8]/' scene.toml
wait_for grep -q "^reload (scene.toml): changed: Material" log.txt || fail "no reload line"
for _ in $(seq 1 300); do [ "$(grep -c 'watching for changes' log.txt)" -ge 2 ] && break; sleep 0.1; done
logged() { page "document.getElementById('log').textContent" | grep -q "reload (scene.toml): changed: Material"; }
wait_for logged || fail "the open page did not receive the reload line"
wait_for shown || fail "the page does not show the new finished image"
sleep 0.5  # the new image element decodes and paints
shot after.png

# The image sits centred under the header (x 240..560, y 47..239 in the 800x600 window), the
# sphere at its left: compare the mean colour of a square inside the sphere.
stats() { oiiotool "$1" --cut 50x50+315+115 --printstats | grep "Stats Avg" | head -1; }
B=$(stats before.png) A=$(stats after.png)
echo "before: $B"
echo "after:  $A"
read -r _ _ br bg bb _ <<< "$(echo "$B" | tr -s ' ')"
read -r _ _ ar ag ab _ <<< "$(echo "$A" | tr -s ' ')"
awk -v br="$br" -v bb="$bb" -v ar="$ar" -v ab="$ab" 'BEGIN {
    # Before: the sphere is red; after: blue.
    exit !((br - bb) > 0.2 && (ab - ar) > 0.2) }' ||
    fail "the screenshot did not turn from red to blue (before $B, after $A)"
curl -s -X DELETE "$WD/session/$SID" > /dev/null
echo "PASS: the open page followed the edit"
