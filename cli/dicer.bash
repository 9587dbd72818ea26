# bash completion for dicer (installed as
# share/bash-completion/completions/dicer; needs Debian's bash-completion).
# Commands and each command's options are read from the binary's own help
# (`dicer --help`, `dicer CMD --help`), so they cannot drift from it; file
# names are offered by kind: meshes for sheets and dice, stores for the
# rest, CAD for mesh-coarse and --geometry.

_dicer_commands()
{
    "$1" --help 2>/dev/null |
        awk '/^Commands/ { on = 1; next } on && /^$/ { exit } on && /^  [a-z]/ { print $1 }'
}

_dicer()
{
    local cur prev words cword split
    _init_completion -s || return

    if ((cword == 1)); then
        COMPREPLY=($(compgen -W "$(_dicer_commands "$1") --help --version" -- "$cur"))
        return
    fi
    local cmd=${words[1]}

    case $prev in
        -o | --output | --points)
            _filedir
            return
            ;;
        --geometry)
            _filedir '@(step|stp|brep|brp)'
            return
            ;;
        --intervals-file)
            _filedir json
            return
            ;;
        --format)
            case $cmd in
                export) COMPREPLY=($(compgen -W 'vtkhdf msh msh-ascii exodus' -- "$cur")) ;;
                transfer) COMPREPLY=($(compgen -W 'hdf5 petsc' -- "$cur")) ;;
            esac
            return
            ;;
    esac
    # Any other option that takes a value ("  --threads N   ..." in the
    # help): a number or a list, nothing to offer.
    if [[ $prev == -* ]] && "$1" "$cmd" --help 2>/dev/null |
        grep -Eq -- "^  (-[a-z], )?$prev[ =][^ ]"; then
        return
    fi
    $split && return

    if [[ $cur == -* ]]; then
        COMPREPLY=($(compgen -W '$(_parse_help "$1" "$cmd --help")' -- "$cur"))
        return
    fi
    case $cmd in
        mesh-coarse) _filedir '@(step|stp|brep|brp)' ;;
        sheets | dice) _filedir '@(e|exo|ex2|g|msh)' ;;
        transfer) _filedir '@(h5|e|exo|ex2|g|msh)' ;;
        *) _filedir h5 ;;
    esac
} &&
    complete -F _dicer dicer
