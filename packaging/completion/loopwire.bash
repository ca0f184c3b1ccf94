# bash completion for loopwire. The candidates come from `loopwire __complete`, which answers
# from the commands' own definitions and the device profiles: command names, options, choices,
# device ids, and the parameter names of the device given with --device.
_loopwire() {
    local cur words cword
    if declare -F _get_comp_words_by_ref >/dev/null; then
        _get_comp_words_by_ref -n =: cur words cword  # keep tc10@4:SP.HL and NAME=VALUE one word
    else
        words=("${COMP_WORDS[@]}") cword=$COMP_CWORD cur=${COMP_WORDS[COMP_CWORD]}
    fi
    local IFS=$'\n'
    local -a answer
    answer=($("${words[0]}" __complete -- "${words[@]:1:cword}" 2>/dev/null)) || return 0
    COMPREPLY=()
    case ${answer[0]} in
        files)
            compopt -o filenames 2>/dev/null
            COMPREPLY=($(compgen -f -- "$cur")) ;;
        words)
            COMPREPLY=("${answer[@]:1}")
            # DEVICE@ and NAME= wait for the rest of the word
            [[ ${COMPREPLY[*]} == *[@=] ]] && compopt -o nospace 2>/dev/null
            declare -F __ltrim_colon_completions >/dev/null && __ltrim_colon_completions "$cur" ;;
    esac
    return 0
}
complete -F _loopwire loopwire
