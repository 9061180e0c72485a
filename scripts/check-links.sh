#!/usr/bin/env bash
# Checks the relative links and images of README.md, CHANGELOG.md and docs/*.md, offline:
# every `[text](path)` and `![alt](path)` outside code must name an existing file or folder,
# and a `#anchor` (alone, or after a path to a markdown file) must match a heading's
# GitHub-style slug there. Links with a scheme (https:, mailto:) are not checked.
#
#   scripts/check-links.sh [FILE.md ...]      (default: README.md CHANGELOG.md docs/*.md)
#
# Exit 1, with one line per broken link, when any is broken.
set -euo pipefail
export LC_ALL=C
cd "$(dirname "${BASH_SOURCE[0]}")/.."

if [ "$#" -gt 0 ]; then
    files=("$@")
else
    shopt -s nullglob
    files=(README.md CHANGELOG.md docs/*.md)
fi

# Prints the text of a markdown file with fenced code blocks blanked (line numbers kept) and
# inline code spans removed.
strip_code() {
    awk '
        /^[ \t]*(```|~~~)/ { fence = !fence; print ""; next }
        fence { print ""; next }
        { gsub(/`[^`]*`/, ""); print }
    ' "$1"
}

# Prints the GitHub-style slug of every heading of a markdown file, one a line, duplicates
# numbered (-1, -2, ...) as GitHub numbers them.
slugs() {
    awk '
        /^[ \t]*(```|~~~)/ { fence = !fence; next }
        fence { next }
        /^#+[ \t]/ {
            t = $0
            sub(/^#+[ \t]+/, "", t)
            sub(/[ \t]+#+[ \t]*$/, "", t)
            # Links keep their text; images, code marks and HTML tags lose their markup.
            while (match(t, /!?\[[^]]*\]\([^)]*\)/)) {
                m = substr(t, RSTART, RLENGTH)
                sub(/^!?\[/, "", m); sub(/\]\(.*$/, "", m)
                t = substr(t, 1, RSTART - 1) m substr(t, RSTART + RLENGTH)
            }
            gsub(/<[^>]*>/, "", t)
            t = tolower(t)
            # Common non-ASCII punctuation (GitHub drops it); other non-ASCII bytes are kept.
            gsub(/\342\200[\223\224\230\231\234\235\246]/, "", t)
            gsub(/[^a-z0-9 _\200-\377-]/, "", t)
            gsub(/ /, "-", t)
            if (t in seen) { n = seen[t]; seen[t] = n + 1; t = t "-" n } else { seen[t] = 1 }
            print t
        }
    ' "$1"
}

status=0
checked=0
for f in "${files[@]}"; do
    if [ ! -f "$f" ]; then
        echo "check-links: $f: missing" >&2
        status=1
        continue
    fi
    dir="$(dirname "$f")"
    while IFS=$'\t' read -r line target; do
        checked=$((checked + 1))
        # Drop an optional title and angle brackets: [t](<path> "title").
        target="${target%% \"*}"
        target="${target#<}"
        target="${target%>}"
        case "$target" in
            '' | [a-zA-Z]*:*) continue ;;
        esac
        path="${target%%#*}"
        anchor=""
        [ "$path" != "$target" ] && anchor="${target#*#}"
        path="${path//%20/ }"
        if [ -z "$path" ]; then
            resolved="$f"
        else
            resolved="$dir/$path"
        fi
        if [ ! -e "$resolved" ]; then
            echo "$f:$line: broken link: $target (no $resolved)" >&2
            status=1
            continue
        fi
        if [ -n "$anchor" ]; then
            case "$resolved" in
                *.md)
                    if ! slugs "$resolved" | grep -qxF -- "$anchor"; then
                        echo "$f:$line: broken anchor: $target (no heading #$anchor in $resolved)" >&2
                        status=1
                    fi
                    ;;
            esac
        fi
    done < <(strip_code "$f" | awk '
        {
            s = $0
            while (match(s, /\]\([^)[:space:]]*( "[^"]*")?\)/)) {
                t = substr(s, RSTART + 2, RLENGTH - 3)
                printf "%d\t%s\n", NR, t
                s = substr(s, RSTART + RLENGTH)
            }
        }
    ')
done

if [ "$status" = 0 ]; then
    echo "check-links: ${#files[@]} files, $checked links, all resolve"
fi
exit "$status"
